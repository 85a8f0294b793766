"""Vectorised (over cells) assembly of P1/Q1 forms, loads, post-processing and error norms.

Matrices are assembled in chunks of `CHUNK` cells: the quadrature data and local matrices of
one chunk, not of the whole mesh, are alive at a time, and their values are summed into the
matrix's final sparsity pattern (built first from the cells' dof pairs, so it is the same
whatever the chunk size: explicit zeros where entries cancel are kept).

Dof numbering: displacement component k of node i is dof 2 i + k; scalar fields (the electric
potential) have dof = node index. Voigt order on (xx, yy, xy) with engineering shear strain
γ_xy = 2 ε_xy. Sign convention of the paper: σ = C ε(u) + eᵀ∇φ, D = e ε(u) − κ∇φ.

Functions `func` given to loads, interpolation and error norms are called as func(x, y) with
arrays of any shape and return x.shape + (ncomp,) (or x.shape when ncomp = 1); a constant (float
or length-ncomp sequence) may be given instead.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .elements import reference_element
from .mesh import Mesh

Func = Callable[[np.ndarray, np.ndarray], np.ndarray] | float | Sequence[float]


@dataclass(frozen=True, eq=False)
class Geometry:
    """Quadrature data of all cells.

    x : (n_cells, n_qp, 2) physical quadrature points.
    w : (n_cells, n_qp) quadrature weights × |det J|.
    phi : (n_qp, n_loc) shape function values.
    grad : (n_cells, n_qp, n_loc, 2) physical shape function gradients.
    """

    x: np.ndarray
    w: np.ndarray
    phi: np.ndarray
    grad: np.ndarray


def _det(J: np.ndarray) -> np.ndarray:
    """Determinants of a stack of 2×2 matrices (..., 2, 2) -> (...)."""
    return J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]


CHUNK = 16384  # cells per assembly chunk


def _geometry(mesh: Mesh, pts: np.ndarray, wts: np.ndarray, cells: slice = slice(None)) -> Geometry:
    """Quadrature data of the cells mesh.cells[cells] (a slice: first cell = its start)."""
    ref = reference_element(mesh.cell_type)
    X = mesh.points[mesh.cells[cells]]  # (n_cells, n_loc, 2)
    # det J is constant (P1) or affine in the reference coordinates (Q1): it is positive on the
    # whole cell iff it is positive at the vertices
    XT = X.transpose(0, 2, 1)[:, None]  # (n_cells, 1, 2, n_loc)
    Jv = XT @ ref.gradients(ref.vertices)  # (n_cells, n_loc, 2, 2) J at the vertices
    bad = np.flatnonzero((_det(Jv) <= 0).any(axis=1)) + (cells.start or 0)  # (n_bad,)
    if bad.size:
        raise ValueError(
            f"inverted or degenerate cell {bad[0]} (nodes {mesh.cells[bad[0]].tolist()}): "
            f"det J <= 0; {bad.size} bad cell(s) in total"
        )
    phi = ref.values(pts)  # (n_qp, n_loc)
    dphi = ref.gradients(pts)  # (n_qp, n_loc, 2)
    J = XT @ dphi  # (n_cells, n_qp, 2, 2) J_ij = ∂x_i/∂ξ_j
    detJ = _det(J)  # (n_cells, n_qp)
    adj = np.stack([J[..., 1, 1], -J[..., 0, 1], -J[..., 1, 0], J[..., 0, 0]], axis=-1)
    invJ = adj.reshape(J.shape) / detJ[..., None, None]  # (n_cells, n_qp, 2, 2)
    grad = dphi @ invJ  # (n_cells, n_qp, n_loc, 2) ∇φ = J⁻ᵀ ∇_ξ φ
    x = phi @ X  # (n_cells, n_qp, 2)
    w = wts[None, :] * detJ  # (n_cells, n_qp)
    return Geometry(x=x, w=w, phi=phi, grad=grad)


def cell_geometry(mesh: Mesh, order: int = 2) -> Geometry:
    """Quadrature points, weights, shape values and physical gradients for a rule of `order`.

    Raises ValueError naming the first cell whose Jacobian determinant is ≤ 0 (inverted).
    """
    pts, wts = reference_element(mesh.cell_type).quadrature(order)
    return _geometry(mesh, pts, wts)


def _vector_dofs(mesh: Mesh) -> np.ndarray:
    """(n_cells, 2 n_loc) global dofs 2 i + k, local order 2 a + k."""
    return (2 * mesh.cells[:, :, None] + np.arange(2)).reshape(mesh.n_cells, -1)


def _keys(rows: np.ndarray, cols: np.ndarray, ncol: int) -> np.ndarray:
    """(k, r, c) flat positions row · ncol + col of the local entries of k cells."""
    return rows[:, :, None].astype(np.int64) * ncol + cols[:, None, :]


def _pattern(rows: np.ndarray, cols: np.ndarray, shape, chunk: int) -> sp.csr_matrix:
    """The sparsity pattern (sorted csr, int8 ones) of all cells' (rows, cols) dof pairs."""
    P = sp.csr_matrix(shape, dtype=np.float32)
    for lo in range(0, rows.shape[0], chunk):
        R, C = rows[lo : lo + chunk], cols[lo : lo + chunk]  # (k, r), (k, c)
        k = _keys(R, C, shape[1]).ravel()  # (k r c,)
        one = np.ones(k.size, dtype=np.float32)  # positive: no cancellation in the sum
        P = P + sp.csr_matrix((one, (k // shape[1], k % shape[1])), shape=shape)
    P.sort_indices()
    return P


def _assemble_chunks(
    local_of: Callable[[slice], np.ndarray],
    rows: np.ndarray,
    cols: np.ndarray,
    shape: tuple[int, int],
    chunk: int = CHUNK,
) -> sp.csr_matrix:
    """Σ over cells of the local matrices local_of(cells) (k, r, c) of each chunk `cells` of k
    cells, at the dofs rows (n_cells, r) × cols (n_cells, c), summed into the final pattern."""
    if chunk < 1:
        raise ValueError(f"chunk must be ≥ 1 cell, got {chunk}")
    P = _pattern(rows, cols, shape, chunk)
    keys = np.repeat(np.arange(shape[0], dtype=np.int64), np.diff(P.indptr))  # (nnz,)
    keys *= shape[1]
    keys += P.indices  # (nnz,) increasing (sorted csr)
    data = np.zeros(P.nnz)  # (nnz,)
    for lo in range(0, rows.shape[0], chunk):
        cells = slice(lo, lo + chunk)
        local = local_of(cells)  # (k, r, c)
        pos = np.searchsorted(keys, _keys(rows[cells], cols[cells], shape[1]))  # (k, r, c)
        np.add.at(data, pos.ravel(), local.ravel())
    del keys
    return sp.csr_matrix((data, P.indices, P.indptr), shape=shape)


def _assemble_forms(
    mesh: Mesh,
    kernel: Callable[[Geometry], np.ndarray],
    rows: np.ndarray,
    cols: np.ndarray,
    shape: tuple[int, int],
    chunk: int = CHUNK,
) -> sp.csr_matrix:
    """Σ over cells of kernel(g) (k, r, c), g the order-2 quadrature data of a chunk of k
    cells, computed chunk by chunk."""
    pts, wts = reference_element(mesh.cell_type).quadrature(2)
    return _assemble_chunks(
        lambda cells: kernel(_geometry(mesh, pts, wts, cells)), rows, cols, shape, chunk
    )


def _strain_operator(grad: np.ndarray) -> np.ndarray:
    """Voigt strain-displacement matrices B: (n_cells, n_qp, 3, 2 n_loc), local dof 2 a + k."""
    n_cells, n_qp, n_loc, _ = grad.shape
    B = np.zeros((n_cells, n_qp, 3, n_loc, 2))  # (n_cells, n_qp, 3, n_loc, 2)
    B[:, :, 0, :, 0] = grad[..., 0]
    B[:, :, 1, :, 1] = grad[..., 1]
    B[:, :, 2, :, 0] = grad[..., 1]
    B[:, :, 2, :, 1] = grad[..., 0]
    return B.reshape(n_cells, n_qp, 3, 2 * n_loc)


def _check_matrix(name: str, M: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    M = np.asarray(M, dtype=float)
    if M.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {M.shape}")
    return M


def elasticity_matrix(mesh: Mesh, C: np.ndarray, chunk: int = CHUNK) -> sp.csr_matrix:
    """(2N × 2N) ∫ C ε(u)·ε(v), C the 3×3 Voigt matrix on (xx, yy, xy); `chunk` cells at a
    time (module docstring)."""
    C = _check_matrix("C", C, (3, 3))

    def kernel(g: Geometry) -> np.ndarray:
        B = _strain_operator(g.grad)  # (k, n_qp, 3, 2 n_loc)
        wBt = (B * g.w[:, :, None, None]).transpose(0, 1, 3, 2)  # (k, n_qp, 2 n_loc, 3)
        return (wBt @ (C @ B)).sum(axis=1)  # (k, 2 n_loc, 2 n_loc)

    dofs = _vector_dofs(mesh)  # (n_cells, 2 n_loc)
    n = 2 * mesh.n_nodes
    return _assemble_forms(mesh, kernel, dofs, dofs, (n, n), chunk)


def coupling_matrix(mesh: Mesh, e: np.ndarray, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × 2N) G[θ, u] = ∫ ∇θ · (e ε(u)), e the 2×3 piezoelectric matrix (rows D_x, D_y)."""
    e = _check_matrix("e", e, (2, 3))

    def kernel(g: Geometry) -> np.ndarray:
        B = _strain_operator(g.grad)  # (k, n_qp, 3, 2 n_loc)
        wgrad = g.grad * g.w[:, :, None, None]  # (k, n_qp, n_loc, 2)
        return (wgrad @ (e @ B)).sum(axis=1)  # (k, n_loc, 2 n_loc)

    shape = (mesh.n_nodes, 2 * mesh.n_nodes)
    return _assemble_forms(mesh, kernel, mesh.cells, _vector_dofs(mesh), shape, chunk)


def permittivity_matrix(mesh: Mesh, kappa: np.ndarray, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × N) ∫ κ∇φ·∇θ, κ a 2×2 symmetric positive definite matrix."""
    kappa = _check_matrix("kappa", kappa, (2, 2))

    def kernel(g: Geometry) -> np.ndarray:
        wgrad = g.grad * g.w[:, :, None, None]  # (k, n_qp, n_loc, 2)
        return (wgrad @ kappa @ g.grad.transpose(0, 1, 3, 2)).sum(axis=1)  # (k, n_loc, n_loc)

    shape = (mesh.n_nodes, mesh.n_nodes)
    return _assemble_forms(mesh, kernel, mesh.cells, mesh.cells, shape, chunk)


def stiffness_matrix(mesh: Mesh, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × N) ∫ ∇φ·∇θ (the H¹ seminorm Gram matrix)."""
    return permittivity_matrix(mesh, np.eye(2), chunk)


def mass_matrix(mesh: Mesh, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × N) ∫ φ θ (the L² Gram matrix)."""

    def kernel(g: Geometry) -> np.ndarray:
        return np.einsum("cq,qa,qb->cab", g.w, g.phi, g.phi, optimize=True)  # (k, n_loc, n_loc)

    shape = (mesh.n_nodes, mesh.n_nodes)
    return _assemble_forms(mesh, kernel, mesh.cells, mesh.cells, shape, chunk)


def _evaluate(func: Func, x: np.ndarray, y: np.ndarray, ncomp: int) -> np.ndarray:
    """func at points (x, y) of any shape as an array x.shape + (ncomp,)."""
    shape = x.shape + (ncomp,)
    if callable(func):
        v = np.asarray(func(x, y), dtype=float)
        if ncomp == 1 and v.shape == x.shape:
            v = v[..., None]
        ok = v.shape == shape or v.ndim == 0
    else:
        v = np.asarray(func, dtype=float)
        ok = v.size == ncomp and v.ndim <= 1
        v = v.reshape(-1)  # (ncomp,)
    if not ok:
        what = "function values" if callable(func) else "constant"
        raise ValueError(f"{what} of shape {v.shape} do not fit points {x.shape}, ncomp={ncomp}")
    return np.broadcast_to(v, shape)


def _scatter(local: np.ndarray, nodes: np.ndarray, n_nodes: int) -> np.ndarray:
    """Sum local nodal vectors (n_items, n_loc, ncomp) into the interleaved global vector."""
    ncomp = local.shape[-1]
    dofs = ncomp * nodes[:, :, None] + np.arange(ncomp)  # (n_items, n_loc, ncomp)
    return np.bincount(dofs.ravel(), weights=local.ravel(), minlength=ncomp * n_nodes)


def volume_load(mesh: Mesh, func: Func, ncomp: int, order: int = 4) -> np.ndarray:
    """∫_Ω f·v dx as a vector of length ncomp·N (interleaved: dof ncomp·i + k)."""
    g = cell_geometry(mesh, order)
    f = _evaluate(func, g.x[..., 0], g.x[..., 1], ncomp)  # (n_cells, n_qp, ncomp)
    Fe = np.einsum("cq,qa,cqk->cak", g.w, g.phi, f, optimize=True)  # (n_cells, n_loc, ncomp)
    return _scatter(Fe, mesh.cells, mesh.n_nodes)


_GAUSS3_T = 0.5 + 0.5 * np.sqrt(0.6) * np.array([-1.0, 0.0, 1.0])  # (3,) on [0, 1]
_GAUSS3_W = np.array([5.0, 8.0, 5.0]) / 18.0  # (3,) sum 1


def boundary_load(mesh: Mesh, name: str, func: Func, ncomp: int) -> np.ndarray:
    """∫_Γ f·v ds over boundary part `name` (straight segments, 3-point Gauss per edge).

    Same layout and `func` conventions as `volume_load`; KeyError for an unknown part.
    """
    if name not in mesh.boundaries:
        raise KeyError(
            f"unknown boundary {name!r}; this mesh has: {', '.join(sorted(mesh.boundaries))}"
        )
    edges = mesh.boundaries[name]  # (n_e, 2)
    P = mesh.points[edges]  # (n_e, 2, 2)
    L = np.linalg.norm(P[:, 1] - P[:, 0], axis=1)  # (n_e,)
    N = np.stack([1 - _GAUSS3_T, _GAUSS3_T], axis=1)  # (3, 2) trace shape functions
    x = np.einsum("qa,eai->eqi", N, P, optimize=True)  # (n_e, 3, 2)
    f = _evaluate(func, x[..., 0], x[..., 1], ncomp)  # (n_e, 3, ncomp)
    Fe = np.einsum("e,q,qa,eqk->eak", L, _GAUSS3_W, N, f, optimize=True)  # (n_e, 2, ncomp)
    return _scatter(Fe, edges, mesh.n_nodes)


def cell_gradients(
    mesh: Mesh, u: np.ndarray, phi: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """Strain ε(u) in Voigt order (xx, yy, 2xy) (n_cells, 3) and ∇φ (n_cells, 2) (None if
    `phi` is None) at the cell centroids."""
    ref = reference_element(mesh.cell_type)
    g = _geometry(mesh, ref.centroid[None, :], np.ones(1))
    grad = g.grad[:, 0]  # (n_cells, n_loc, 2)
    U = np.asarray(u, dtype=float).reshape(mesh.n_nodes, 2)[mesh.cells]  # (n_cells, n_loc, 2)
    Du = np.einsum("cak,cai->cki", U, grad, optimize=True)  # (n_cells, 2, 2) ∂u_k/∂x_i
    eps = np.stack([Du[:, 0, 0], Du[:, 1, 1], Du[:, 0, 1] + Du[:, 1, 0]], axis=1)  # (n_cells, 3)
    if phi is None:
        return eps, None
    return eps, np.einsum("ca,cai->ci", np.asarray(phi, dtype=float)[mesh.cells], grad)


def cell_fields(
    mesh: Mesh,
    u: np.ndarray,
    phi: np.ndarray | None,
    C: np.ndarray,
    e: np.ndarray | None,
    kappa: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Stress σ = Cε(u) + eᵀ∇φ (n_cells, 3) and electric displacement D = eε(u) − κ∇φ
    (n_cells, 2) at the cell centroids.

    With `phi` None (purely elastic body) σ = Cε(u), D = 0 and `e`, `kappa` are ignored.
    """
    C = _check_matrix("C", C, (3, 3))
    eps, E = cell_gradients(mesh, u, phi)  # (n_cells, 3), (n_cells, 2) ∇φ
    sigma = eps @ C.T  # (n_cells, 3)
    if phi is None:
        return sigma, np.zeros((mesh.n_cells, 2))
    e = _check_matrix("e", e, (2, 3))
    kappa = _check_matrix("kappa", kappa, (2, 2))
    return sigma + E @ e, eps @ e.T - E @ kappa.T


def interpolate(mesh: Mesh, func: Func, ncomp: int) -> np.ndarray:
    """Nodal interpolant: vector of length ncomp·N (interleaved)."""
    x, y = mesh.points.T  # (N,) each
    return np.array(_evaluate(func, x, y, ncomp)).ravel()


def l2_error(mesh: Mesh, uh: np.ndarray, exact: Func, ncomp: int, order: int = 4) -> float:
    """‖u − u_h‖_{L²(Ω)} by quadrature of `order` (uh interleaved, length ncomp·N)."""
    g = cell_geometry(mesh, order)
    U = np.asarray(uh, dtype=float).reshape(mesh.n_nodes, ncomp)[mesh.cells]  # (n_c, n_loc, nc)
    vh = np.einsum("qa,cak->cqk", g.phi, U, optimize=True)  # (n_cells, n_qp, ncomp)
    d = _evaluate(exact, g.x[..., 0], g.x[..., 1], ncomp) - vh  # (n_cells, n_qp, ncomp)
    return float(np.sqrt(np.einsum("cq,cqk,cqk->", g.w, d, d)))


def h1_seminorm_error(
    mesh: Mesh, uh: np.ndarray, grad_exact: Callable, ncomp: int, order: int = 4
) -> float:
    """|u − u_h|_{H¹(Ω)}; grad_exact(x, y) returns x.shape + (ncomp, 2) (or x.shape + (2,))."""
    g = cell_geometry(mesh, order)
    U = np.asarray(uh, dtype=float).reshape(mesh.n_nodes, ncomp)[mesh.cells]  # (n_c, n_loc, nc)
    Gh = np.einsum("cqai,cak->cqki", g.grad, U, optimize=True)  # (n_cells, n_qp, ncomp, 2)
    x, y = g.x[..., 0], g.x[..., 1]  # (n_cells, n_qp) each
    G = np.asarray(grad_exact(x, y), dtype=float)  # (n_cells, n_qp, ncomp, 2)
    if ncomp == 1 and G.shape == x.shape + (2,):
        G = G[..., None, :]
    if G.shape != x.shape + (ncomp, 2):
        raise ValueError(f"grad_exact returned shape {G.shape}, expected {x.shape + (ncomp, 2)}")
    d = G - Gh  # (n_cells, n_qp, ncomp, 2)
    return float(np.sqrt(np.einsum("cq,cqki,cqki->", g.w, d, d)))
