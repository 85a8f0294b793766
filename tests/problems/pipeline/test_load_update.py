"""The load-step update of the contact plug-ins (`update(model, scene, t)`, contract;
`problems.plugins.contact.model.update`) against the full rebuild of every step
(`solve_path(..., rebuild=True)`): every step's displacement, potential and multiplier must be
the same to rounding, on every shipped load-path scene and on drawn load paths of a
piezoelectric block (displacement, potential, traction and charge all depending on t).

Mutations (a hook with a stale term): the tractions forgotten, the prescribed values of an
earlier step kept — each must fail the comparison on a scene whose that term changes along the
path. A value other than loads and boundary data depending on t (a friction coefficient) must
make the step a rebuild."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import problems.pipeline as pipeline
from problems.pipeline.load_path import solve_path
from problems.plugins.contact import bodies
from problems.plugins.contact import model as contact_model
from problems.scene import SCENES_DIR, Scene
from problems.scene.fields import load_parameter

RTOL = 1e-12  # relative to the largest entry of the step's field: rounding only


def load_path_scenes() -> list[str]:
    """The shipped scenes with a [load_path]."""
    out = []
    for p in sorted(SCENES_DIR.glob("*.toml")):
        if "load_path" in tomllib.loads(p.read_text()):
            out.append(p.stem)
    return out


def steps(loaded: pipeline.Loaded, rebuild: bool, level: int | None = None) -> list[tuple]:
    """(u, λ, updated) of every step of the path."""
    out: list[tuple] = []
    solve_path(
        loaded,
        level=level,
        rebuild=rebuild,
        on_step=lambda s: out.append(
            (s.solution.u.copy(), s.solution.lam.copy(), s.record["updated"])
        ),
    )
    return out


def mismatch(a: list[tuple], b: list[tuple]) -> float:
    """The largest relative difference between two paths' steps (inf: different lengths)."""
    if len(a) != len(b):
        return np.inf
    worst = 0.0
    for (ua, la, _), (ub, lb, _) in zip(a, b, strict=True):
        for x, y in ((ua, ub), (la, lb)):
            scale = max(float(np.abs(y).max(initial=0.0)), 1e-300)
            worst = max(worst, float(np.abs(x - y).max(initial=0.0)) / scale)
    return worst


def assert_same(updated: list[tuple], rebuilt: list[tuple]) -> None:
    assert len(updated) == len(rebuilt) >= 2
    assert not any(r[2] for r in rebuilt)
    assert all(r[2] for r in updated[1:]), "every step after the first is an update"
    assert mismatch(updated, rebuilt) <= RTOL


def test_scenes_found():
    assert {"shear_strip_path", "block3d_liftoff"} <= set(load_path_scenes())


@pytest.mark.parametrize("name", load_path_scenes())
def test_update_matches_rebuild_on_shipped_scenes(name):
    loaded = pipeline.load(name)
    assert_same(steps(loaded, rebuild=False), steps(loaded, rebuild=True))


def problem_mismatch(loaded: pipeline.Loaded) -> float:
    """The largest relative difference in f, gap and the prescribed values between each step's
    MixedVI updated from the step before and the one the build gives (operators and Λ must be
    the same: AssertionError)."""
    plugin, ts = loaded.plugin, loaded.spec.load_path.values()
    with load_parameter(ts[0]):
        prev = plugin.build(loaded.scene, None)
    worst = 0.0
    for t in ts[1:]:
        with load_parameter(t):
            built = plugin.build(loaded.scene, None)
            updated = plugin.update(prev, loaded.scene, t)
        a, b = built.vi, updated.vi
        for x, y in ((a.f, b.f), (a.gap, b.gap), (built.values, updated.values)):
            scale = max(float(np.abs(x).max(initial=0.0)), 1e-300)
            worst = max(worst, float(np.abs(x - y).max(initial=0.0)) / scale)
        assert (a.A != b.A).nnz == 0 and (a.B != b.B).nnz == 0
        assert repr(a.Lambda) == repr(b.Lambda)
        prev = updated
    return worst


@pytest.mark.parametrize("name", load_path_scenes())
def test_updated_problem_is_the_built_one(name):
    """Each step's MixedVI from the update of the step before is the one the build gives,
    independently of the solver."""
    assert problem_mismatch(pipeline.load(name)) <= RTOL


def piezo_block(seed: int) -> pipeline.Loaded:
    """A BaTiO3 block on a rigid base (unilateral Coulomb contact) with drawn t-dependent data:
    the top pressed and shifted, its potential, a traction on the left, a charge on the right."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 5))
    a = rng.uniform(-1.0, 1.0, size=8)
    F = float(rng.uniform(0.05, 0.4))
    text = f"""
format = 2
[scene]
plugin = "contact"
level = 0
[load_path]
t = {[float(k) for k in range(1, n + 1)]}
[bodies.block]
material = "BaTiO3"
geometry = {{ kind = "rectangle", x = [0.0, 2.0], y = [0.0, 1.0], cells = [4, 2] }}
[[bodies.block.displacement]]
boundary = "top"
value = ["{a[0]:.6e}*1e-8*t", "-1.0e-7*(1.0 + {abs(a[1]):.6e}*t)"]
[[bodies.block.potential]]
boundary = "top"
value = "{a[2]:.6e}*5.0*t"
[[bodies.block.potential]]
boundary = "bottom"
value = 0.0
[[bodies.block.traction]]
boundary = "left"
value = ["{a[3]:.6e}*1e3*t*(1.0 + y)", "{a[4]:.6e}*1e3*t"]
[[bodies.block.charge]]
boundary = "right"
value = "{a[5]:.6e}*1e-7*t*y"
[contact]
slave = "block.bottom"
law = "unilateral"
friction = "coulomb"
F = {F!r}
"""
    return pipeline.validated(Scene(data=tomllib.loads(text), path="<block>", name="block"))


@settings(max_examples=6)
@given(seed=st.integers(0, 2**32 - 1))
def test_update_matches_rebuild_on_drawn_paths(seed):
    loaded = piezo_block(seed)
    assert_same(steps(loaded, rebuild=False), steps(loaded, rebuild=True))


def test_t_in_the_friction_coefficient_rebuilds():
    loaded = piezo_block(0)
    loaded.scene.data["contact"]["F"] = "0.2 + 0.01*t"
    loaded = pipeline.validated(loaded.scene)
    out = steps(loaded, rebuild=False)
    assert len(out) >= 2 and not any(r[2] for r in out)


def test_forgotten_traction_fails(monkeypatch):
    """Mutation: the hook re-reads the Dirichlet data but forgets the tractions (the strip's
    side tractions change for t ≤ 1)."""
    loaded = pipeline.load("shear_strip_path")
    rebuilt = steps(loaded, rebuild=True)
    assert mismatch(steps(loaded, rebuild=False), rebuilt) <= RTOL

    def no_traction(section, body):
        return bodies.loads(section.model_copy(update={"traction": []}), body)

    monkeypatch.setattr(contact_model, "loads", no_traction)
    assert mismatch(steps(loaded, rebuild=False), rebuilt) > 1e-6
    assert problem_mismatch(loaded) > 1e-6


def test_stale_prescribed_values_fail(monkeypatch):
    """Mutation: the hook keeps the prescribed values of its first update (the drawn block's
    top displacement and potential change every step)."""
    loaded = piezo_block(1)
    rebuilt = steps(loaded, rebuild=True)
    first: dict[str, tuple] = {}

    def stale(section, body):
        return first.setdefault(body.name, bodies.dirichlet(section, body))

    monkeypatch.setattr(contact_model, "dirichlet", stale)
    assert len(rebuilt) >= 3
    assert mismatch(steps(loaded, rebuild=False), rebuilt) > 1e-6
    first.clear()
    assert problem_mismatch(loaded) > 1e-6
