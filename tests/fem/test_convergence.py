"""A manufactured solution of 3D linear piezoelectricity (no contact) on curved hexahedral and
tetrahedral meshes: observed rates in H¹ (≈ 1) and L² (≈ 2) for u and φ.

Exact fields: sums of plane waves u_k = Σ_m A_km sin(a_m·x + b_m), φ likewise; BaTiO3 poled along
a direction that is no coordinate axis (every block of C, e, κ full), made dimensionless.
Loads from the full tensors: f_i = −∂_j σ_ij, σ_ij = c_ijkl ∂_l u_k + e_kij ∂_k φ, and
q = div D, D_i = e_ijk ∂_k u_j − κ_ij ∂_j φ; Dirichlet data on the whole boundary.

The study for the record (the table up to n = 16 cells per direction):
    .venv/bin/pytest tests/fem/test_convergence.py -m slow -s -o addopts=""
"""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import fem.assembly as asm
from fem.assembly import h1_seminorm_error, interpolate, l2_error, volume_load
from fem.meshing import box, transform
from fem.tensors import NAMED, Material3D, poled

from .helpers import full_tensors

C0, K0 = 1e10, 1e-8
_M = poled(NAMED["BaTiO3"], [0.3, -0.5, 0.8])
MAT = Material3D("BaTiO3 (scaled)", _M.C / C0, _M.e / np.sqrt(C0 * K0), _M.kappa / K0)


class PlaneWaves:
    """f(x) = Σ_m amp[:, m] sin(a_m·x + b_m) with value, gradient and Hessian."""

    def __init__(self, amp: np.ndarray, a: np.ndarray, b: np.ndarray):
        self.amp, self.a, self.b = amp, a, b  # (ncomp, n_w), (n_w, 3), (n_w,)

    def _theta(self, x, y, z):
        return np.stack([x, y, z], -1) @ self.a.T + self.b  # (..., n_w)

    def value(self, x, y, z):
        return np.sin(self._theta(x, y, z)) @ self.amp.T  # (..., ncomp)

    def grad(self, x, y, z):
        c = np.cos(self._theta(x, y, z))  # (..., n_w)
        return np.einsum("...m,km,mj->...kj", c, self.amp, self.a)  # (..., ncomp, 3)

    def hess(self, x, y, z):
        s = np.sin(self._theta(x, y, z))  # (..., n_w)
        return -np.einsum("...m,km,mj,ml->...kjl", s, self.amp, self.a, self.a)  # (..., nc, 3, 3)


rng = np.random.default_rng(2024)
U = PlaneWaves(rng.uniform(-1, 1, (3, 3)), rng.uniform(-2.5, 2.5, (3, 3)), rng.uniform(0, 6, 3))
PHI = PlaneWaves(rng.uniform(-1, 1, (1, 3)), rng.uniform(-2.5, 2.5, (3, 3)), rng.uniform(0, 6, 3))


def body_force(x, y, z):
    c, e = full_tensors(MAT)
    Hu, Hp = U.hess(x, y, z), PHI.hess(x, y, z)[..., 0, :, :]  # (..., 3, 3, 3), (..., 3, 3)
    return -(np.einsum("ijkl,...kjl->...i", c, Hu) + np.einsum("kij,...jk->...i", e, Hp))


def charge(x, y, z):
    _, e = full_tensors(MAT)
    Hu, Hp = U.hess(x, y, z), PHI.hess(x, y, z)[..., 0, :, :]
    return np.einsum("ijk,...jik->...", e, Hu) - np.einsum("ij,...ij->...", MAT.kappa, Hp)


def wavy(p: np.ndarray, amount: float = 0.08) -> np.ndarray:
    x, y, z = p.T
    b = np.stack([x * (1 - x), y * (1 - y), z * (1 - z)], axis=1)
    s = np.stack([np.sin(3 * y + 2 * z), np.cos(2 * x - z), np.sin(x + 2 * y)], axis=1)
    return p + 4 * amount * b * s


def solve_mms(element: str, n: int) -> dict[str, float]:
    mesh = transform(box((0, 1), (0, 1), (0, 1), (n, n, n), element), wavy)
    N = mesh.n_nodes
    A = asm.piezo_matrix(mesh, MAT.C, MAT.e, MAT.kappa).tocsr()
    F = np.concatenate([volume_load(mesh, body_force, 3), volume_load(mesh, charge, 1)])
    bnd = np.unique(np.concatenate([f.ravel() for f in mesh.boundaries.values()]))
    fixed = np.zeros(4 * N, dtype=bool)
    fixed[(3 * bnd[:, None] + np.arange(3)).ravel()] = True
    fixed[3 * N + bnd] = True
    x = np.concatenate([interpolate(mesh, U.value, 3), interpolate(mesh, PHI.value, 1)])
    free = np.flatnonzero(~fixed)
    rhs = F[free] - A[free][:, fixed] @ x[fixed]
    x[free] = spla.spsolve(sp.csc_matrix(A[free][:, free]), rhs)
    u, phi = x[: 3 * N], x[3 * N :]
    return {
        "h": 1.0 / n,
        "dofs": 4 * N,
        "u_L2": l2_error(mesh, u, U.value, 3),
        "u_H1": h1_seminorm_error(mesh, u, U.grad, 3),
        "phi_L2": l2_error(mesh, phi, lambda *p: PHI.value(*p)[..., 0], 1),
        "phi_H1": h1_seminorm_error(mesh, phi, lambda *p: PHI.grad(*p)[..., 0, :], 1),
    }


def rates(rows: list[dict[str, float]]) -> dict[str, np.ndarray]:
    keys = ("u_L2", "u_H1", "phi_L2", "phi_H1")
    return {
        k: np.array([np.log2(a[k] / b[k]) for a, b in zip(rows[:-1], rows[1:], strict=True)])
        for k in keys
    }


def rates_ok(rows: list[dict[str, float]], h1: float = 0.9, l2: float = 1.8) -> bool:
    """The check: on the finest pair, H¹ rates > h1 and L² rates > l2 for u and φ."""
    r = rates(rows)
    return all(r[k][-1] > h1 for k in ("u_H1", "phi_H1")) and all(
        r[k][-1] > l2 for k in ("u_L2", "phi_L2")
    )


def table(element: str, rows: list[dict[str, float]]) -> str:
    r = rates(rows)
    lines = [f"{element}: n, dofs, u_L2 (rate), u_H1 (rate), phi_L2 (rate), phi_H1 (rate)"]
    for i, row in enumerate(rows):
        cells = [f"{round(1 / row['h']):3d}", f"{row['dofs']:6d}"]
        for k in ("u_L2", "u_H1", "phi_L2", "phi_H1"):
            rate = f"({r[k][i - 1]:.2f})" if i else "(  - )"
            cells.append(f"{row[k]:.3e} {rate}")
        lines.append("  ".join(cells))
    return "\n".join(lines)


def test_the_exact_fields_satisfy_their_derivatives():
    """The manufactured data are only as good as the closed-form derivatives: check them."""
    p = np.random.default_rng(1).uniform(0, 1, (5, 3))
    x, y, z = p.T
    h = 1e-5
    for f in (U, PHI):
        for j in range(3):
            d = np.zeros(3)
            d[j] = h
            fd = (f.value(*(p + d).T) - f.value(*(p - d).T)) / (2 * h)  # (5, nc)
            assert np.allclose(f.grad(x, y, z)[..., j], fd, atol=1e-8)
            fd2 = (f.grad(*(p + d).T) - f.grad(*(p - d).T)) / (2 * h)  # (5, nc, 3)
            assert np.allclose(f.hess(x, y, z)[..., j], fd2, atol=1e-7)


@pytest.mark.parametrize("element", ["hexahedron", "tetra"])
def test_manufactured_piezo_rates(element):
    rows = [solve_mms(element, n) for n in (2, 4, 8)]
    print("\n" + table(element, rows))
    assert rates_ok(rows), table(element, rows)


def test_rates_catch_a_flipped_coupling_sign(monkeypatch):
    """Fault: the coupling blocks enter with the wrong signs; the scheme no longer converges."""
    good = asm.piezo_matrix

    def flipped(mesh, C, e, kappa):
        A = good(mesh, C, e, kappa).tolil()
        N3 = 3 * mesh.n_nodes
        A[:N3, N3:] = -A[:N3, N3:]
        A[N3:, :N3] = -A[N3:, :N3]
        return A.tocsr()

    monkeypatch.setattr(asm, "piezo_matrix", flipped)
    rows = [solve_mms("tetra", n) for n in (4, 8)]
    assert not rates_ok(rows)
    assert rates(rows)["phi_H1"][-1] < 0.5  # φ diverges from the exact one


@pytest.mark.slow
@pytest.mark.parametrize("element", ["hexahedron", "tetra"])
def test_manufactured_piezo_rates_study(element):
    rows = [solve_mms(element, n) for n in (2, 4, 8, 16)]
    print("\n" + table(element, rows))
    assert rates_ok(rows, h1=0.95, l2=1.9), table(element, rows)
