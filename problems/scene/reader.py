"""Scene files (TOML): loading, `--set dotted.key=value` overrides, and checked access.

Every access goes through `Table`, which knows its dotted path, so any error names the key,
the value and what is allowed; `Table.finish()` refuses unknown keys with a did-you-mean.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from problems.errors import SceneError

from .expressions import ALLOWED as EXPR_ALLOWED
from .expressions import ExpressionError, compile_expression

SCENES_DIR = Path(__file__).parent.parent / "scenes"
MAX_MAGNITUDE = 1e100  # |number| in a scene; larger ones overflow when squared in assembly


@dataclass
class Scene:
    """A parsed scene: the TOML tree, where it came from, and its short name."""

    data: dict
    path: str
    name: str

    def root(self) -> Table:
        """The checked view of the whole scene."""
        return Table(self.data, "")


def find_scene(name_or_path: str) -> Path:
    """A scene file by path, or by the name of a shipped scene (`mixvi scenes`)."""
    p = Path(name_or_path)
    try:  # a name too long for the file system, or otherwise unusable: not found
        if p.is_file():
            return p
        shipped = SCENES_DIR / f"{name_or_path}.toml"
        if shipped.is_file():
            return shipped
    except (OSError, ValueError):
        pass
    names = sorted(q.stem for q in SCENES_DIR.glob("*.toml"))
    hint = difflib.get_close_matches(name_or_path, names, n=1)
    extra = f" (did you mean {hint[0]!r}?)" if hint else ""
    raise SceneError(
        "scene", name_or_path, f"an existing file or a shipped scene: {', '.join(names)}{extra}"
    )


def parse_override(text: str) -> tuple[list[str], Any]:
    """'contact.g=5e7' → (['contact', 'g'], 5e7); values are TOML literals, else strings."""
    if "=" not in text:
        raise SceneError("--set", text, "dotted.key=value, e.g. contact.g=5e7")
    key, raw = text.split("=", 1)
    parts = [p.strip() for p in key.strip().split(".")]
    if not all(parts):
        raise SceneError("--set", text, "dotted.key=value, e.g. contact.g=5e7")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return parts, value


def load_scene(name_or_path: str, overrides: Iterable[str] = ()) -> Scene:
    """Read a scene file and apply `--set` overrides (SceneError on any problem)."""
    path = find_scene(name_or_path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise SceneError("(file)", path.name, f"valid TOML ({err})", str(path)) from None
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError("(file)", path.name, f"a readable text file ({err})", str(path)) from None
    for text in overrides:
        parts, value = parse_override(text)
        node = data
        for p in parts[:-1]:
            if p not in node or not isinstance(node[p], dict):
                raise SceneError(
                    f"--set {'.'.join(parts)}",
                    value,
                    f"a key inside existing tables ({p!r} missing)",
                    str(path),
                )
            node = node[p]
        node[parts[-1]] = value
    return Scene(data=data, path=str(path), name=path.stem)


def _did_you_mean(word: str, options: Iterable[str]) -> str:
    hint = difflib.get_close_matches(word, list(options), n=1)
    return f" (did you mean {hint[0]!r}?)" if hint else ""


class Table:
    """A checked view of a TOML table at a dotted path."""

    def __init__(self, data: dict, path: str):
        self.data = data
        self.path = path
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: Any = ..., allowed: str = "a value") -> Any:
        self.used.add(name)
        if name not in self.data:
            if default is ...:
                raise SceneError(self.key(name), None, f"required ({allowed})")
            return default
        return self.data[name]

    def table(self, name: str, required: bool = True) -> Table | None:
        v = self.raw(name, ... if required else None, "a table")
        if v is None:
            return None
        if not isinstance(v, dict):
            raise SceneError(self.key(name), v, "a table")
        return Table(v, self.key(name))

    def tables(self, name: str) -> list[Table]:
        """An array of tables ([[name]]), empty if absent."""
        v = self.raw(name, [], "an array of tables")
        if isinstance(v, dict):
            v = [v]
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            raise SceneError(self.key(name), v, "an array of tables ([[...]])")
        return [Table(x, f"{self.key(name)}[{i}]") for i, x in enumerate(v)]

    def number(
        self,
        name: str,
        default: Any = ...,
        lo: float | None = None,
        hi: float | None = None,
        lo_open: bool = False,
    ) -> float:
        v = self.raw(name, default, "a number")
        ok = isinstance(v, int | float) and not isinstance(v, bool) and _moderate(v)
        if not ok:
            rng = _range(lo, hi, lo_open)
            raise SceneError(self.key(name), v, f"a finite number{rng} of size ≤ {MAX_MAGNITUDE:g}")
        if (lo is not None and (v < lo or (lo_open and v == lo))) or (hi is not None and v > hi):
            raise SceneError(self.key(name), v, "a number" + _range(lo, hi, lo_open))
        return float(v)

    def integer(self, name: str, default: Any = ..., lo: int = 0, hi: int | None = None) -> int:
        v = self.raw(name, default, "an integer")
        if not isinstance(v, int) or isinstance(v, bool) or v < lo or (hi is not None and v > hi):
            rng = f" ≥ {lo}" + (f" and ≤ {hi}" if hi is not None else "")
            raise SceneError(self.key(name), v, f"an integer{rng}")
        return v

    def string(self, name: str, default: Any = ..., choices: Iterable[str] | None = None) -> str:
        v = self.raw(name, default, "a string")
        if not isinstance(v, str):
            raise SceneError(self.key(name), v, "a string")
        if choices is not None:
            choices = list(choices)
            if v not in choices:
                raise SceneError(
                    self.key(name), v, "one of " + ", ".join(choices) + _did_you_mean(v, choices)
                )
        return v

    def pair(self, name: str, default: Any = ..., kind: type = float) -> tuple:
        v = self.raw(name, default, "a pair [a, b]")
        good = (
            isinstance(v, list)
            and len(v) == 2
            and all(isinstance(x, int | float) and not isinstance(x, bool) for x in v)
            and all(_moderate(x) for x in v)
            and (kind is float or all(isinstance(x, int) for x in v))
        )
        if not good:
            what = "integers" if kind is int else f"finite numbers of size ≤ {MAX_MAGNITUDE:g}"
            raise SceneError(self.key(name), v, f"a pair [a, b] of {what}")
        return tuple(kind(x) for x in v)

    def field(self, name: str, ncomp: int, default: Any = ...) -> Callable[..., np.ndarray]:
        """A constant or expression-valued field of (x, y) with `ncomp` components.

        Accepts a number / expression string (ncomp = 1) or a list of them (ncomp > 1).
        Returns f(x, y) → array of shape x.shape (ncomp = 1) or x.shape + (ncomp,).
        """
        v = self.raw(name, default, "a number or expression")
        items = v if isinstance(v, list) else [v]
        if len(items) != ncomp:
            what = "a number or expression" if ncomp == 1 else f"a list of {ncomp} entries"
            raise SceneError(self.key(name), v, what + f", each a number or {EXPR_ALLOWED}")
        fns = []
        for it in items:
            if isinstance(it, int | float) and not isinstance(it, bool):
                if not _moderate(it):
                    raise SceneError(
                        self.key(name), v, f"finite numbers of size ≤ {MAX_MAGNITUDE:g}"
                    )
                fns.append(_const(float(it)))
            elif isinstance(it, str):
                try:
                    fns.append(compile_expression(it))
                except ExpressionError as err:
                    raise SceneError(self.key(name), it, f"{EXPR_ALLOWED}; {err}") from None
            else:
                raise SceneError(self.key(name), v, f"numbers or {EXPR_ALLOWED}")
        key = self.key(name)

        def fn(x, y):
            parts = [np.broadcast_to(f(x, y), np.shape(x)) for f in fns]
            out = parts[0] if ncomp == 1 else np.stack(parts, axis=-1)
            if not (np.isfinite(out).all() and (np.abs(out) <= MAX_MAGNITUDE).all()):
                raise SceneError(
                    key, v, f"an expression finite and of size ≤ {MAX_MAGNITUDE:g} on the domain"
                )
            return out

        fn.constant = all(getattr(f, "constant", False) for f in fns)
        return fn

    def finish(self, allowed_extra: Iterable[str] = ()) -> None:
        """Refuse keys that were never read (unknown keys), with a did-you-mean."""
        known = self.used | set(allowed_extra)
        for k in self.data:
            if k not in known:
                raise SceneError(
                    self.key(k),
                    self.data[k],
                    "unknown key"
                    + _did_you_mean(k, known)
                    + f"; known here: {', '.join(sorted(known))}",
                )


def _moderate(v: float) -> bool:
    """Finite and of size ≤ MAX_MAGNITUDE."""
    return math.isfinite(v) and abs(v) <= MAX_MAGNITUDE


def _const(c: float) -> Callable:
    def f(x, y):
        return np.full(np.shape(x), c)

    f.constant = True
    return f


def _range(lo, hi, lo_open) -> str:
    if lo is None and hi is None:
        return ""
    if hi is None:
        return f" {'>' if lo_open else '≥'} {lo:g}"
    if lo is None:
        return f" ≤ {hi:g}"
    return f" in {'(' if lo_open else '['}{lo:g}, {hi:g}]"
