"""The iterative linear path on the shipped scenes: amg agrees with the direct solver on every
scene at levels 0 and 1; the plug-ins' field data (rigid-body modes) is right and is used."""

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import problems.scenes
import vi_core
from problems.plugins import registry
from problems.plugins.contact.bodies import field_data, operator
from problems.scene import load_scene
from vi_core import MixedVI
from vi_core import ssn as ssn_module

pytest.importorskip("pyamg")

SCENES = sorted(p.stem for p in Path(problems.scenes.__path__[0]).glob("*.toml"))
TOL = 1e-10


def _model(name: str, level: int):
    scene = load_scene(name, [])
    return registry.for_scene(scene).build(scene, level)


# level 1 of the two costliest 3D scenes (~10 s of CPU of the CI tier's ~60 s here) runs in the
# slow tier; CI keeps their level 0 and level 1 of every other scene, 3D ones included
SLOW_LEVEL_1 = {"spherical_cap", "bracket3d"}


@pytest.mark.parametrize(
    ("name", "level"),
    [
        pytest.param(name, level, marks=[pytest.mark.slow] * (level == 1 and name in SLOW_LEVEL_1))
        for name in SCENES
        for level in (0, 1)
    ],
)
def test_amg_agrees_with_direct_on_every_shipped_scene(name, level):
    vi = _model(name, level).vi
    d = vi_core.solve(vi, "ssn", tol=TOL, linear_solver="splu", estimate_condition=True)
    a = vi_core.solve(vi, "ssn", tol=TOL, linear_solver="amg")
    assert d.converged and a.converged and a.residual <= TOL
    s = vi.scaling.s_u
    diff = np.linalg.norm((a.u - d.u) / s) / max(np.linalg.norm(d.u / s), 1e-300)
    assert diff <= 2 * d.info["condition_estimate"] * TOL  # forward error ≤ κ · residual each
    if vi.m:  # every contact scene condenses: the Krylov path ran, without fallback
        assert a.info["linear_solver"] == "amg"
        assert len(a.info["krylov_iterations"]) == a.iterations
        assert a.info["fallback"] == []


@pytest.mark.parametrize("name", ["paper_two_body", "rigid_foundation", "signorini", "block3d"])
def test_field_data_rigid_body_modes_are_null_vectors(name):
    """Without Dirichlet reduction the displacement block annihilates the rigid-body modes (3
    in 2D, 6 in 3D; mutation: a rotation with the wrong sign in one component does not)."""
    model = _model(name, 1)
    bodies = model.bodies if hasattr(model, "bodies") else [model.body]
    A = sp.block_diag([operator(b) for b in bodies], format="csr")
    n_full = A.shape[0]
    data = field_data(bodies, np.arange(n_full), n_full)
    disp = data["fields"]["displacement"]
    modes = data["near_null"]["displacement"]  # (n_disp, 3 or 6)
    assert modes.shape[1] == {2: 3, 3: 6}[bodies[0].dim]
    K = A[disp][:, disp]
    scale = abs(K).max() * np.abs(modes).max()
    assert np.abs(K @ modes).max() <= 1e-9 * scale
    wrong = modes[:, -1].copy()  # the rotation about z, (−y, x)
    wrong[modes[:, 1] == 1] *= -1  # (−y, −x): not a rotation
    assert np.abs(K @ wrong).max() > 1e-3 * scale
    if model.vi.fields is not None:
        assert set(model.vi.fields) <= {"displacement", "potential"}


def _tied_iterations(vi: MixedVI) -> int:
    """GMRES iterations of one condensed Newton system (every multiplier tied) to 1e-8."""
    e = vi.equilibrated
    st = ssn_module._Stepper(e, True, "amg", TOL)
    st.step(sp.identity(e.m, format="csr"), sp.csr_matrix((e.m, e.m)), np.zeros(e.m), None, 1e-8)
    rec = st.krylov.steps[-1]
    assert rec["fallback"] is None
    return rec["iterations"]


def test_wrong_near_null_space_costs_iterations():
    """Measured on the paper scene, level 1: 14 iterations with the rigid-body modes, 33 with
    the scalar default (no near-null space) — the modes must reach the hierarchy."""
    vi = _model("paper_two_body", 1).vi
    good = _tied_iterations(vi)
    bare = MixedVI(vi.A, vi.B, vi.f, vi.Lambda, vi.gap, fields=vi.fields)
    assert _tied_iterations(bare) >= 2 * good
