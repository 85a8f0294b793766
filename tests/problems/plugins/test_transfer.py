"""`transfer.prolongate`: a coarse level's displacement and potential carried to the next
level of a 2D two-body scene, checked on affine fields (which P1/Q1 interpolation and
extrapolation reproduce exactly, curved boundaries included), and of a 3D scene with the fine
prescribed values kept."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from problems.plugins import transfer
from problems.plugins.contact import plane as pc
from problems.plugins.contact import solid as contact3d
from problems.scene import load_scene


def _affine(model, coef: np.ndarray) -> np.ndarray:
    """(n_full,) every body's fields c_k0 + c_k1 x + c_k2 y, k = u_x, u_y, φ (coef (3, 3))."""
    x = np.zeros(model.values.size)
    for b in model.bodies:
        P = b.mesh.points  # (N, 2)
        vals = coef[:, 0] + P @ coef[:, 1:].T  # (N, 3)
        x[b.u_dofs(np.arange(b.n_nodes)).ravel()] = vals[:, :2].ravel()
        if b.has_potential:
            x[b.phi_dofs(np.arange(b.n_nodes))] = vals[:, 2]
    return x


def _error(name: str, seed: int) -> tuple[float, int]:
    """max |prolongate(affine) − affine| / max |affine| from level 0 to 1 (the fine prescribed
    values on the fixed entries), and the fine nodes found outside the coarse mesh."""
    scene = load_scene(name)
    coarse, fine = pc.build(scene, 0), pc.build(scene, 1)
    coef = np.random.default_rng(seed).standard_normal((3, 3))
    y, outside = transfer.prolongate(coarse, _affine(coarse, coef), fine)
    want = _affine(fine, coef)
    fixed = np.ones(want.size, dtype=bool)
    fixed[fine.free] = False
    want[fixed] = fine.values[fixed]
    return float(np.abs(y - want).max() / np.abs(want).max()), outside


@pytest.mark.parametrize("name", ["paper_two_body", "shear_strip_two_body"])
@settings(max_examples=5)
@given(seed=st.integers(0, 2**32 - 1))
def test_affine_fields_are_carried_exactly(name, seed):
    """Both bodies, both displacement components and the cradle's potential; the curved
    scene's new arc nodes lie outside the coarse mesh (extrapolated, still exact), the
    rectangles' meshes are nested (none outside)."""
    err, outside = _error(name, seed=seed)
    assert err <= 1e-12
    assert (outside > 0) == (name == "paper_two_body")


def test_affine_check_catches_faults(monkeypatch):
    """The check above fails for the fields' columns mixed up and for cells not inverted
    (every point at its cell's centre)."""
    values, locate = transfer.interpolate, transfer.locate
    monkeypatch.setattr(transfer, "interpolate", lambda *a: np.roll(values(*a), 1, axis=1))
    assert _error("paper_two_body", 0)[0] > 1e-3
    monkeypatch.setattr(transfer, "interpolate", values)

    def centres(mesh, pts, candidates=None):
        cell, xi, out = locate(mesh, pts, candidates)
        return cell, np.zeros_like(xi) + (1 / 3 if mesh.cell_type == "triangle" else 0), out

    monkeypatch.setattr(transfer, "locate", centres)
    assert _error("shear_strip_two_body", 0)[0] > 1e-3


def test_prolongate_keeps_the_fine_prescribed_values():
    """3D: the fixed entries of the fine full vector are the fine level's Dirichlet values,
    the free ones the coarse field: an affine coarse displacement (P1 exact) on the bracket."""
    scene = load_scene("bracket3d")
    coarse, fine = contact3d.build(scene, 0), contact3d.build(scene, 1)
    x = np.zeros(coarse.values.size)
    for b in coarse.bodies:
        d = b.u_dofs(np.arange(b.n_nodes))  # (N, 3)
        x[d] = b.mesh.points @ np.array([[1.0, 0.0, 2.0], [0.0, -1.0, 0.0], [0.5, 0.0, 1.0]])
    out, outside = transfer.prolongate(coarse, x, fine)
    assert outside == 0
    fixed = np.ones(out.size, dtype=bool)
    fixed[fine.free] = False
    np.testing.assert_array_equal(out[fixed], fine.values[fixed])
    for b in fine.bodies:
        d = b.u_dofs(np.arange(b.n_nodes))  # (N, 3)
        want = b.mesh.points @ np.array([[1.0, 0.0, 2.0], [0.0, -1.0, 0.0], [0.5, 0.0, 1.0]])
        free = ~fixed[d]
        np.testing.assert_allclose(out[d][free], want[free], rtol=0, atol=1e-12)
