"""`transfer.prolongate`: a coarse level's displacement and potential carried to the next
level of a two-body scene, checked on affine fields (which P1/Q1 interpolation and
extrapolation reproduce exactly, curved boundaries included)."""

import numpy as np
import pytest

from problems.plugins import piezo_contact as pc
from problems.plugins import transfer
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
    """max |prolongate(affine) − affine| / max |affine| from level 0 to 1, and the fine nodes
    found outside the coarse mesh."""
    scene = load_scene(name)
    coarse, fine = pc.build(scene, 0), pc.build(scene, 1)
    coef = np.random.default_rng(seed).standard_normal((3, 3))
    y, outside = transfer.prolongate(coarse, _affine(coarse, coef), fine)
    want = _affine(fine, coef)
    return float(np.abs(y - want).max() / np.abs(want).max()), outside


@pytest.mark.parametrize("name", ["paper_two_body", "shear_strip_two_body"])
def test_affine_fields_are_carried_exactly(name):
    """Both bodies, both displacement components and the cradle's potential; the curved
    scene's new arc nodes lie outside the coarse mesh (extrapolated, still exact), the
    rectangles' meshes are nested (none outside)."""
    err, outside = _error(name, seed=int(np.random.default_rng().integers(2**32)))
    assert err <= 1e-12
    assert (outside > 0) == (name == "paper_two_body")


def test_affine_check_catches_faults(monkeypatch):
    """The check above fails for the fields' columns mixed up and for cells not inverted
    (every point at its cell's centre)."""
    values, locate = transfer._values, transfer.locate
    monkeypatch.setattr(transfer, "_values", lambda *a: np.roll(values(*a), 1, axis=1))
    assert _error("paper_two_body", 0)[0] > 1e-3
    monkeypatch.setattr(transfer, "_values", values)

    def centres(mesh, pts, candidates=8):
        cell, xi, out = locate(mesh, pts, candidates)
        return cell, np.zeros_like(xi) + (1 / 3 if mesh.cell_type == "triangle" else 0), out

    monkeypatch.setattr(transfer, "locate", centres)
    assert _error("shear_strip_two_body", 0)[0] > 1e-3
