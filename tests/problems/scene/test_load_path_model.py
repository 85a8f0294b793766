"""The [load_path] section and the load parameter t in scene expressions: t only with a load
path (otherwise an error naming the field, for any expression field of any shipped scene), the
forms `steps` / `end` / `t`, and where an expression is evaluated (inside a load step at its t,
outside one at the path's last t)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from problems.errors import SceneError
from problems.plugins import registry
from problems.scene import SCENES_DIR, load_scene
from problems.scene.fields import Expression, load_parameter
from problems.scene.model import expressions

SHIPPED = sorted(p.stem for p in SCENES_DIR.glob("*.toml"))


def _spec(scene):
    return scene.validated(registry.for_scene(scene).SCENE_MODEL)


def _set(data: dict, path: str, value) -> None:
    """Set the raw scene value at a dotted path with [i] indices (an expression's `path`)."""
    keys: list = []
    for part in path.split("."):
        name, *idx = re.split(r"\[|\]\[|\]", part)
        keys.append(name)
        keys += [int(i) for i in idx if i != ""]
    node = data
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value


def _expression_paths(name: str) -> list[str]:
    return [e.path for e in expressions(_spec(load_scene(name)))]


WITHOUT_PATH = [n for n in SHIPPED if "load_path" not in load_scene(n).data]
CASES = [(name, path) for name in WITHOUT_PATH for path in _expression_paths(name)]


@settings(max_examples=40)
@given(st.sampled_from(CASES), st.integers(0, 2**32 - 1))
def test_t_without_a_load_path_is_refused_naming_the_field(case, seed):
    """Any expression field of any shipped scene rewritten to use t: refused at exactly that
    field unless the scene has a [load_path]; with one it validates and is evaluated at t."""
    name, path = case
    rng = np.random.default_rng(seed)
    scale = float(rng.uniform(0.5, 2.0))
    scene = load_scene(name)
    text = f"0*x + {scale!r}*t"
    _set(scene.data, path, text)
    with pytest.raises(SceneError) as err:
        _spec(scene)
    assert err.value.key == path and err.value.value == text
    assert "[load_path]" in str(err.value)

    steps = int(rng.integers(1, 6))
    scene.data["load_path"] = {"steps": steps}
    spec = _spec(scene)
    (e,) = [e for e in expressions(spec) if e.path == path]
    assert e.uses_t and e.t_end == 1.0
    x = rng.uniform(-1, 1, 3)
    args = (x,) * 3 if spec.DIMENSION == 3 else (x,) * 2  # a 3D scene: f(x, y, z)
    assert np.allclose(e(*args), scale)  # outside a step: the path's last t
    t = float(rng.uniform(0, 1))
    with load_parameter(t):
        assert np.allclose(e(*args), scale * t)


@pytest.mark.parametrize(
    ("table", "values"),
    [
        ({"steps": 4}, [0.25, 0.5, 0.75, 1.0]),
        ({"steps": 2, "end": 3.0}, [1.5, 3.0]),
        ({"t": [0.0, 1.0, 2.5]}, [0.0, 1.0, 2.5]),
        ({"t": [7]}, [7.0]),
    ],
)
def test_the_forms_of_a_load_path(table, values):
    scene = load_scene("shear_strip")
    scene.data["load_path"] = table
    assert _spec(scene).load_path.values() == values


@pytest.mark.parametrize(
    ("table", "key", "words"),
    [
        ({}, "load_path.steps", "required"),
        ({"steps": 2, "t": [1.0]}, "load_path.t", "absent with `steps"),
        ({"t": [1.0], "end": 2.0}, "load_path.end", "absent with `t"),
        ({"t": [0.5, 0.5]}, "load_path.t[1]", "above the one before"),
        ({"t": [1.0, 0.2]}, "load_path.t[1]", "above the one before"),
        ({"t": [-1.0]}, "load_path.t[0]", "≥ 0"),
        ({"t": []}, "load_path.t", "1 or more"),
        ({"steps": 0}, "load_path.steps", "≥ 1"),
        ({"steps": 1.5}, "load_path.steps", "an integer"),
        ({"steps": 1001}, "load_path.steps", "≤ 1000"),
        ({"steps": 2, "end": 0.0}, "load_path.end", "> 0"),
        ({"step": 2}, "load_path.step", "did you mean 'steps'"),
    ],
)
def test_a_bad_load_path_is_refused_naming_the_field(table, key, words):
    scene = load_scene("shear_strip")
    scene.data["load_path"] = table
    with pytest.raises(SceneError) as err:
        _spec(scene)
    assert err.value.key == key and words in str(err.value), str(err.value)


def test_an_override_that_brings_t_is_named():
    scene = load_scene("shear_strip", ["contact.g='6e5*t'"])
    with pytest.raises(SceneError) as err:
        _spec(scene)
    assert err.value.key == "contact.g" and "--set contact.g='6e5*t'" in str(err.value)


def test_t_keeps_the_expression_safety_checks():
    for text in ("t(1)", "t.real", "t[0]", "__import__('os')", "t if x else y", "lambda: t"):
        with pytest.raises(Exception, match="not allowed|unknown name|syntax"):
            Expression.parse(text)


def test_an_expression_of_t_evaluated_without_a_load_path_names_its_field():
    """Outside validation (an Expression made by hand) there is no path to take t from."""
    e = Expression("1 + t")
    e.path = "contact.g"
    with pytest.raises(SceneError, match="contact.g.*no \\[load_path\\]"):
        e(np.zeros(2), np.zeros(2))
    with load_parameter(0.5):
        assert np.array_equal(e(np.zeros(2), np.zeros(2)), [1.5, 1.5])


def test_a_non_finite_value_names_t():
    e = Expression("1/(t - 0.5)")
    e.path = "bodies.b.traction[0].value[1]"
    with load_parameter(0.5), pytest.raises(SceneError, match=r"t = 0\.5"):
        e(np.zeros(1), np.zeros(1))
