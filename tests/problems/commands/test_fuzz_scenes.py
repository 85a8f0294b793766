"""Hypothesis-fuzzed scene files through the `mixvi` entry point: whatever the file holds,
`mixvi solve FILE --level 0` ends with exit status 0, 1 or 2 — never 3 (an internal error),
never a traceback — and with 2 exactly one line naming the file, leaving no output folder;
the scene file itself is never modified.

Each example takes a shipped scene and applies one to three mutations: a value replaced by a
hostile one at a random place in the tree (numbers at the extremes, NaN, wrong types, nested
lists and tables, expressions from a small grammar with wrong arities and unknown names, text),
a key deleted or added, or the TOML text itself cut or spliced with random bytes.

    CI tier (40 examples):   .venv/bin/pytest tests/problems/commands/test_fuzz_scenes.py
    fuzz tier (1000):        .venv/bin/pytest -m fuzz
"""

from __future__ import annotations

import contextlib
import io
import math
import tempfile
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from problems.commands.main import main
from problems.scene import SCENES_DIR

SHIPPED = ["rigid_foundation", "obstacle", "antiplane", "signorini", "manufactured"]
TEXTS = {n: (SCENES_DIR / f"{n}.toml").read_text() for n in SHIPPED}

numbers = st.one_of(
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1e-300, 1e300, 1e100, -1e100, 0.5, 1e-12, 1e12]),
)
FUNCS = ["sin", "cos", "exp", "log", "sqrt", "abs", "where", "maximum", "arctan2", "gamma"]
ATOMS = ["x", "y", "pi", "e", "1", "0", "1e308", "-2", "z", "__import__", "()"]


@st.composite
def expressions(draw, depth: int = 0) -> str:
    """Expressions of x, y from a small grammar, often wrong (arity, names, syntax)."""
    if depth >= 3 or draw(st.booleans()):
        return draw(st.sampled_from(ATOMS))
    kind = draw(st.integers(0, 3))
    if kind == 0:
        f = draw(st.sampled_from(FUNCS))
        args = draw(st.lists(expressions(depth + 1), min_size=0, max_size=3))
        return f"{f}({', '.join(args)})"
    if kind == 1:
        op = draw(st.sampled_from(["+", "-", "*", "/", "**", "<", "%", "//", "@", ","]))
        return f"{draw(expressions(depth + 1))} {op} {draw(expressions(depth + 1))}"
    if kind == 2:
        return f"({draw(expressions(depth + 1))})"
    return draw(st.text(max_size=12))


def values(depth: int = 0):
    leaf = st.one_of(numbers, st.booleans(), expressions(), st.text(max_size=20))
    if depth >= 2:
        return leaf
    return st.one_of(
        leaf,
        st.lists(values(depth + 1), max_size=4),
        st.dictionaries(st.text(min_size=1, max_size=8), values(depth + 1), max_size=3),
    )


def toml_value(v) -> str:
    """A TOML literal for a Python value (inline tables and arrays)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return '"' + v.encode("unicode_escape").decode().replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    items = ", ".join(f"{toml_value(str(k))} = {toml_value(x)}" for k, x in v.items())
    return "{" + items + "}"


def paths(tree, prefix=()):
    """Every (path, value) in a TOML tree (tables and array elements)."""
    yield prefix, tree
    if isinstance(tree, dict):
        for k, v in tree.items():
            yield from paths(v, (*prefix, k))
    elif isinstance(tree, list):
        for i, v in enumerate(tree):
            yield from paths(v, (*prefix, i))


@st.composite
def fuzzed_scene(draw) -> bytes:
    name = draw(st.sampled_from(SHIPPED))
    data = tomllib.loads(TEXTS[name])
    data.setdefault("scene", {})["level"] = 0
    for _ in range(draw(st.integers(1, 3))):
        places = [p for p, _ in paths(data) if p]
        where = draw(st.sampled_from(places))
        parent = data
        for k in where[:-1]:
            parent = parent[k]
        action = draw(st.integers(0, 3))
        if action == 0 and isinstance(parent, dict):
            del parent[where[-1]]
        elif action == 1 and isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=10))] = draw(values())
        else:
            parent[where[-1]] = draw(values())
    text = "".join(f"{toml_value(k)} = {toml_value(v)}\n" for k, v in data.items()).encode()
    if draw(st.integers(0, 4)) == 0:  # damage the text itself
        i = draw(st.integers(0, len(text)))
        j = draw(st.integers(i, min(len(text), i + 40)))
        text = text[:i] + draw(st.binary(max_size=8)) + text[j:]
    return text


def run_fuzzed(text: bytes) -> None:
    with tempfile.TemporaryDirectory() as d:
        scene = Path(d) / "fuzz.toml"
        scene.write_bytes(text)
        out = Path(d) / "out"
        err, std = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
            code = main(["solve", str(scene), "--level", "0", "--out", str(out)])
        msg = err.getvalue()
        assert code in (0, 1, 2), msg
        assert "Traceback" not in msg, msg
        assert scene.read_bytes() == text
        if code == 2:
            assert msg.startswith("mixvi: error: ") and msg.count("\n") == 1, msg
            assert not out.exists()
        else:
            assert (out / ".mixvi-run.json").is_file() and (out / "summary.json").is_file()


@settings(max_examples=40, suppress_health_check=[HealthCheck.too_slow])
@given(fuzzed_scene())
def test_fuzzed_scene_files(text):
    run_fuzzed(text)


@pytest.mark.slow
@pytest.mark.fuzz
@settings(max_examples=1000, suppress_health_check=[HealthCheck.too_slow])
@given(fuzzed_scene())
def test_fuzzed_scene_files_1000(text):
    run_fuzzed(text)
