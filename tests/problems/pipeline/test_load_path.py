"""Load paths through the pipeline (`problems.pipeline.load_path`) against an independent
computation: the shear strip on a rigid base with Tresca friction, whose every state is uniform
(u = (s + γy, 0), exact in Q1), so its history is the 1D stick/slip recursion

    τ_trial = μ(δ_k − s_{k−1})/H;  |τ_trial| ≤ g: s_k = s_{k−1} (stick), else s_k = δ_k ∓ gH/μ,

with δ_k the top displacement of step k. The recursion is history: a loading–unloading path
ends with a residual slip, while one step to the final load (or the total form) gives none.
Mutations: the shift of the incremental form dropped (the hook a no-op) or of the wrong sign
— both must fail the comparison."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import problems.pipeline as pipeline
import vi_core
from problems.pipeline.load_path import solve_path
from problems.plugins.contact import plane as piezo_contact
from problems.scene import Scene
from problems.scene.fields import load_parameter

MU, H = 1.0e9, 1.0  # E = 2.6e9, ν = 0.3: μ = E/(2(1 + ν)) = 1e9 Pa; height 1 m
TOL = 1e-11


def strip(deltas: list[float], g: float, cells: tuple[int, int] = (4, 2)) -> pipeline.Loaded:
    """The strip with its top moved by deltas[k−1] at t = k, both sides rollers (u_y = 0)."""
    delta = " + ".join(
        f"{d!r}*((t > {k - 0.5})*(t < {k + 0.5}))" for k, d in enumerate(deltas, start=1)
    )
    text = f"""
format = 2
[scene]
plugin = "contact"
level = 0
[solver]
tol = {TOL}
[load_path]
t = {list(range(1, len(deltas) + 1))}
[bodies.block]
material = {{ kind = "isotropic", E = 2.6e9, nu = 0.3 }}
geometry = {{ kind = "rectangle", x = [0.0, 2.0], y = [0.0, 1.0], cells = {list(cells)} }}
[[bodies.block.displacement]]
boundary = "top"
value = ["{delta}", 0.0]
[[bodies.block.displacement]]
boundary = "left"
components = "y"
value = [0.0, 0.0]
[[bodies.block.displacement]]
boundary = "right"
components = "y"
value = [0.0, 0.0]
[contact]
slave = "block.bottom"
g = {g!r}
"""
    return pipeline.validated(Scene(data=tomllib.loads(text), path="<strip>", name="strip"))


def recursion(deltas: list[float], g: float) -> list[tuple[float, float]]:
    """(slip s_k, shear stress τ_k) after each step: the 1D stick/slip history."""
    s, out = 0.0, []
    for d in deltas:
        tau = MU * (d - s) / H
        if abs(tau) > g:
            tau = np.sign(tau) * g
            s = d - tau * H / MU
        out.append((s, tau))
    return out


def states(loaded: pipeline.Loaded) -> list[tuple[np.ndarray, np.ndarray]]:
    """(u_x along the bottom, λ_t) of every step of the load path."""
    out = []

    def keep(step):
        st_ = piezo_contact.contact_state(step.model, step.solution)
        assert step.solution.converged
        out.append((st_["ut_slave"], st_["lam_t"]))

    solve_path(loaded, on_step=keep)
    return out


def misfit(deltas: list[float], g: float) -> float:
    """Largest distance between the FE path and the recursion over all steps, relative to
    the displacement gH/μ at which slip starts and to g."""
    ref = recursion(deltas, g)
    worst = 0.0
    for (ut, lam_t), (s, tau) in zip(states(strip(deltas, g)), ref, strict=True):
        worst = max(worst, np.abs(ut - s).max() * MU / (g * H), np.abs(lam_t - tau).max() / g)
    return worst


paths = st.lists(st.floats(-1.0, 1.0), min_size=2, max_size=5)


@settings(max_examples=12)
@given(paths, st.floats(0.1, 0.9), st.integers(0, 2**32 - 1))
def test_the_path_follows_the_stick_slip_history(shape, ratio, seed):
    """Random top displacements (any sign, up and down) and friction bounds: every step of
    the incremental path is the recursion's state, to the solver tolerance."""
    rng = np.random.default_rng(seed)
    dmax = float(rng.uniform(5e-4, 2e-3))
    deltas = [dmax * v for v in shape]
    g = ratio * MU * dmax / H  # slip happens somewhere along most paths
    assert misfit(deltas, g) < 1e-7


@settings(max_examples=6)
@given(st.integers(2, 6), st.floats(0.2, 0.9), st.integers(0, 2**32 - 1))
def test_monotone_proportional_loading_ends_where_one_step_does(n, ratio, seed):
    """δ(t) ∝ t and g fixed (Tresca, λ_n not involved): N steps and one step end in the same
    state (the slip grows monotonically, so the history does not matter)."""
    rng = np.random.default_rng(seed)
    dmax = float(rng.uniform(5e-4, 2e-3)) * float(rng.choice([-1.0, 1.0]))
    g = ratio * MU * abs(dmax) / H
    many = states(strip([dmax * k / n for k in range(1, n + 1)], g))[-1]
    one = states(strip([dmax], g))[-1]
    assert np.allclose(many[0], one[0], rtol=0, atol=1e-8 * abs(dmax))
    assert np.allclose(many[1], one[1], rtol=0, atol=1e-8 * g)


LOAD_UNLOAD = ([5e-4, 1e-3, 5e-4, 0.0], 6e5)  # slips on the way up, sticks on the way down


def test_loading_then_unloading_leaves_a_residual_slip():
    """Up to δ = 1e-3 and back to 0 with g = 6e5: slip s = 4e-4 stays (recursion), while one
    step to δ = 0 (the same final load) leaves the strip unstressed at u = 0."""
    deltas, g = LOAD_UNLOAD
    assert recursion(deltas, g)[-1] == pytest.approx((4e-4, -4e5))
    ut, lam_t = states(strip(deltas, g))[-1]
    assert np.allclose(ut, 4e-4, rtol=1e-8) and np.allclose(lam_t, -4e5, rtol=1e-8)
    ut1, lam1 = states(strip([0.0], g))[-1]
    assert np.abs(ut1).max() == 0.0 and np.abs(lam1).max() == 0.0


def _no_shift(model, previous, previous_sol):
    return None


HOOK = piezo_contact.incremental


def _wrong_sign(model, previous, previous_sol):
    HOOK(model, previous, previous_sol)
    model.vi = model.vi.with_rhs(gap=model.vi.gap - 2 * model.slip_origin)


@pytest.mark.parametrize("mutant", [_no_shift, _wrong_sign], ids=["no_shift", "wrong_sign"])
def test_a_wrong_incremental_form_is_caught(monkeypatch, mutant):
    """Mutations of the hook: the loading–unloading comparison above must fail."""
    monkeypatch.setattr(piezo_contact, "incremental", mutant)
    assert misfit(*LOAD_UNLOAD) > 1e-2


def test_warm_and_cold_paths_agree():
    """Every step but the first is warm-started from the one before; from zero (cold) the
    steps reach the same states."""
    deltas, g = LOAD_UNLOAD
    warm, cold = [], []
    solve_path(strip(deltas, g), on_step=lambda s: warm.append(s))
    solve_path(strip(deltas, g), cold=True, on_step=lambda s: cold.append(s))
    assert [s.record["warm"] for s in warm] == [False, True, True, True]
    assert not any(s.record["warm"] for s in cold)
    for a, b in zip(warm, cold, strict=True):
        assert np.allclose(
            a.solution.u, b.solution.u, rtol=0, atol=1e-8 * np.abs(b.solution.u).max()
        )


@settings(max_examples=4)
@given(st.integers(0, 2**32 - 1))
def test_voltage_and_loads_follow_t_step_by_step(seed):
    """A piezoelectric scene whose potential and traction are functions of t, tied at the
    contact (g huge: nothing slips, so the incremental and total forms coincide): every step
    equals a direct solve of the scene built at that t."""
    rng = np.random.default_rng(seed)
    ts = np.sort(rng.uniform(0.1, 2.0, 3)).round(6).tolist()
    from problems.scene import load_scene

    scene = load_scene("rigid_foundation")
    scene.data["contact"]["g"] = 1e15
    scene.data["load_path"] = {"t": ts}
    body = scene.data["bodies"]["block"]
    for part in body["potential"] if isinstance(body["potential"], list) else [body["potential"]]:
        part["value"] = f"({part['value']}) * (1 + t) + 50*t"
    loaded = pipeline.validated(scene)
    steps = []
    solve_path(loaded, on_step=steps.append)
    assert [s.t for s in steps] == ts
    us = []
    for s in steps:
        with load_parameter(s.t):
            direct = loaded.plugin.build(scene, None)
        sol = vi_core.solve(direct.vi, "ssn", tol=1e-11)
        us.append(sol.u)
        assert np.allclose(s.solution.u, sol.u, rtol=0, atol=1e-7 * np.abs(sol.u).max())
    assert not np.allclose(us[0], us[-1])  # the steps differ: t reached the potential


def test_the_shipped_path_scene_follows_its_closed_form():
    """shear_strip_path (pressed, sheared, unloaded in shear; level 0): at every step the slip
    and λ_t of the recursion and the pressure λ_n = (λ + 2μ) v/H of the uniform compression."""
    loaded = pipeline.load("shear_strip_path")
    ts = loaded.spec.load_path.values()
    deltas = [1e-3 * max(0.0, min(t - 1.0, 3.0 - t)) for t in ts]
    press = [2e-4 * min(t, 1.0) for t in ts]
    ref = recursion(deltas, 4e5)
    got = []
    solve_path(
        loaded, 0, on_step=lambda s: got.append(piezo_contact.contact_state(s.model, s.solution))
    )
    assert len(got) == 30
    for st_, (s, tau), v in zip(got, ref, press, strict=True):
        assert np.allclose(st_["ut_slave"], s, rtol=0, atol=1e-9 * 4e-4)
        assert np.allclose(st_["lam_t"], tau, rtol=0, atol=1e-8 * 4e5)
        assert np.allclose(st_["lam_n"], 3.5e9 * v, rtol=0, atol=1e-8 * 7e5)
    assert ref[-1] == pytest.approx((4e-4, -4e5))  # the residual slip of the unloaded strip


def test_the_python_api_solves_the_path():
    """problems.solve_scene of a load-path scene: the last step, info["steps"]. Three steps
    δ = 0, 1e-3, 0 (pressed throughout): slip 6e-4 forward, then back to gH/μ = 4e-4."""
    import problems

    res = problems.solve_scene("shear_strip_path", level=0, load_path__steps=3)
    assert [s["t"] for s in res.info["steps"]] == [1.0, 2.0, 3.0] and res.info["converged"]
    assert np.allclose(res.contact["ut_slave"], 4e-4, rtol=1e-8)
    assert np.allclose(res.contact["lambda_t"], -4e5, rtol=1e-8)


def coulomb_path(ts: list[float]) -> list[dict]:
    """rigid_foundation (level 0) with unilateral contact and Coulomb friction F = 0.3: pressed
    (t 0 → 1), sheared (1 → 2) and unloaded in shear (2 → 3); the contact state per step."""
    from problems.scene import load_scene

    scene = load_scene("rigid_foundation")
    c = scene.data["contact"]
    c.pop("g")
    c.update(law="unilateral", friction="coulomb", F=0.3)
    scene.data["load_path"] = {"t": ts}
    scene.data["bodies"]["block"]["displacement"][0]["value"] = [
        "2.0e-4*maximum(0.0, minimum(t - 1.0, 3.0 - t))",
        "-1.0e-4*minimum(t, 1.0)",
    ]
    out = []

    def keep(step):
        assert step.solution.converged
        out.append(piezo_contact.contact_state(step.model, step.solution))

    solve_path(pipeline.validated(scene), 0, on_step=keep)
    return out


@pytest.mark.parametrize("mutant", [None, _no_shift], ids=["hook", "no_shift"])
def test_a_coulomb_path_keeps_its_history(monkeypatch, mutant):
    """Unilateral contact with Coulomb friction through the same hook: after shearing and
    unshearing, slip remains that one step to t = 3 does not have; the Lemma 4.2 identity
    holds on the slip increments at every step. Without the shift the history is lost."""
    if mutant is not None:
        monkeypatch.setattr(piezo_contact, "incremental", mutant)
    path = coulomb_path([1.0, 2.0, 3.0])
    one = coulomb_path([3.0])[-1]
    residual = float(np.abs(path[-1]["jump_t"] - one["jump_t"]).max())
    if mutant is None:
        assert residual > 1e-5  # slip ~ 7e-5 m stays (the shear went to 2e-4 m)
        assert max(s["lemma_4_2"] for s in path) < 1e-10
    else:
        assert residual < 1e-12
