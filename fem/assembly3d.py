"""Vectorised (over cells) assembly of 3D P1/Q1 forms, loads, post-processing and error norms.

Matrices are assembled in chunks of `fem.assembly.CHUNK` cells, by the 2D path's pattern and
scatter (`fem.assembly._assemble_chunks`): the quadrature data and local matrices of one chunk
are alive at a time. Computed for all cells at once, the elasticity matrix's were the peak of a
3D solve with AMG (3,456 B per tetrahedron: bracket3d level 2, 406 MiB against the AMG set-up's
246 MiB).

Dof numbering: displacement component k of node i is dof 3 i + k; scalar fields (the electric
potential) have dof = node index. Voigt order (xx, yy, zz, yz, xz, xy) with engineering shear
strains γ_ij = 2 ε_ij (see `fem.tensors`). Sign convention of the paper:
σ = C ε(u) + eᵀ∇φ, D = e ε(u) − κ∇φ; the coupled operator is [[K, Gᵀ], [−G, P]].

Functions `func` given to loads, interpolation and error norms are called as func(x, y, z) with
arrays of any shape and return x.shape + (ncomp,) (or x.shape when ncomp = 1); a constant (float
or length-ncomp sequence) may be given instead.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .assembly import CHUNK, _assemble_chunks, _check_matrix, _scatter
from .elements import reference_element
from .elements3d import FACE_TYPE, reference_element3d
from .jacobians import check_cells, cofactors
from .mesh import Mesh as Mesh3D
from .tensors import VOIGT_PAIRS

Func3 = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | float | Sequence[float]


@dataclass(frozen=True, eq=False)
class Geometry3D:
    """Quadrature data of all cells.

    x : (n_cells, n_qp, 3) physical quadrature points.
    w : (n_cells, n_qp) quadrature weights × det J.
    phi : (n_qp, n_loc) shape function values.
    grad : (n_cells, n_qp, n_loc, 3) physical shape function gradients.
    """

    x: np.ndarray
    w: np.ndarray
    phi: np.ndarray
    grad: np.ndarray


def _geometry(
    mesh: Mesh3D, pts: np.ndarray, wts: np.ndarray, cells: slice = slice(None)
) -> Geometry3D:
    """Quadrature data of the cells mesh.cells[cells] (a slice), not checked for inversion."""
    ref = reference_element3d(mesh.cell_type)
    X = mesh.points[mesh.cells[cells]]  # (n_cells, n_loc, 3)
    phi = ref.values(pts)  # (n_qp, n_loc)
    dphi = ref.gradients(pts)  # (n_qp, n_loc, 3)
    # J is constant on a tetrahedron: compute it once per cell
    at = dphi[:1] if mesh.cell_type == "tetra" else dphi  # (n_J, n_loc, 3), n_J = 1 or n_qp
    J = np.einsum("cai,qaj->cqij", X, at, optimize=True)  # (n_cells, n_J, 3, 3) ∂x_i/∂ξ_j
    cof = cofactors(J)  # (n_cells, n_J, 3, 3)
    detJ = np.einsum("...j,...j->...", J[..., 0, :], cof[..., 0, :])  # (n_cells, n_J) row 0
    invJ = cof.transpose(0, 1, 3, 2) / detJ[..., None, None]  # (n_cells, n_J, 3, 3)
    grad = dphi @ invJ  # (n_cells, n_qp, n_loc, 3) ∇φ = J⁻ᵀ ∇_ξ φ (as rows: ∇_ξφᵀ J⁻¹)
    x = phi @ X  # (n_cells, n_qp, 3)
    w = wts[None, :] * detJ  # (n_cells, n_qp)
    return Geometry3D(x=x, w=w, phi=phi, grad=grad)


def cell_geometry(mesh: Mesh3D, order: int = 2) -> Geometry3D:
    """Quadrature points, weights, shape values and physical gradients for a rule of `order`.

    Raises ValueError naming the first inverted or degenerate cell (`fem.jacobians.check_cells`).
    """
    check_cells(mesh)
    pts, wts = reference_element3d(mesh.cell_type).quadrature(order)
    return _geometry(mesh, pts, wts)


def _assemble_forms(
    mesh: Mesh3D,
    kernel: Callable[[Geometry3D], np.ndarray],
    order: int,
    rows: np.ndarray,
    cols: np.ndarray,
    shape: tuple[int, int],
    chunk: int,
) -> sp.csr_matrix:
    """Σ over cells of kernel(g) (k, r, c), g the quadrature data (rule of `order`) of a chunk
    of k cells, computed chunk by chunk; the cells are checked once first (`check_cells`)."""
    check_cells(mesh)
    pts, wts = reference_element3d(mesh.cell_type).quadrature(order)
    return _assemble_chunks(
        lambda cells: kernel(_geometry(mesh, pts, wts, cells)), rows, cols, shape, chunk
    )


def _order(mesh: Mesh3D) -> int:
    """Quadrature order of the bilinear forms: exact on tetrahedra (constant gradients) and on
    parallelepipeds (Q1 gradients × gradients have degree 2 in each variable)."""
    return 0 if mesh.cell_type == "tetra" else 2


def vector_dofs(mesh: Mesh3D) -> np.ndarray:
    """(n_cells, 3 n_loc) global dofs 3 i + k, local order 3 a + k."""
    return (3 * mesh.cells[:, :, None] + np.arange(3)).reshape(mesh.n_cells, -1)


def strain_operator(grad: np.ndarray) -> np.ndarray:
    """Voigt strain-displacement matrices B: (..., 6, 3 n_loc) from gradients (..., n_loc, 3).

    Row I = (i, j) of `VOIGT_PAIRS`: ε_ii = ∂_i u_i, γ_ij = ∂_j u_i + ∂_i u_j (i ≠ j).
    """
    *lead, n_loc, _ = grad.shape
    B = np.zeros((*lead, 6, n_loc, 3))  # (..., 6, n_loc, 3)
    for row, (i, j) in enumerate(VOIGT_PAIRS):
        B[..., row, :, i] = grad[..., j]
        if i != j:
            B[..., row, :, j] = grad[..., i]
    return B.reshape(*lead, 6, 3 * n_loc)


def elasticity_matrix(mesh: Mesh3D, C: np.ndarray, chunk: int = CHUNK) -> sp.csr_matrix:
    """(3N × 3N) ∫ C ε(u)·ε(v), C the 6×6 Voigt matrix; `chunk` cells at a time."""
    C = _check_matrix("C", C, (6, 6))

    def kernel(g: Geometry3D) -> np.ndarray:
        B = strain_operator(g.grad)  # (k, n_qp, 6, 3 n_loc)
        wBt = (B * g.w[:, :, None, None]).transpose(0, 1, 3, 2)  # (k, n_qp, 3 n_loc, 6)
        return (wBt @ (C @ B)).sum(axis=1)  # (k, 3 n_loc, 3 n_loc)

    dofs = vector_dofs(mesh)  # (n_cells, 3 n_loc)
    n = 3 * mesh.n_nodes
    return _assemble_forms(mesh, kernel, _order(mesh), dofs, dofs, (n, n), chunk)


def coupling_matrix(mesh: Mesh3D, e: np.ndarray, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × 3N) G[θ, u] = ∫ ∇θ · (e ε(u)), e the 3×6 piezoelectric matrix (rows D_x, D_y, D_z);
    `chunk` cells at a time."""
    e = _check_matrix("e", e, (3, 6))

    def kernel(g: Geometry3D) -> np.ndarray:
        B = strain_operator(g.grad)  # (k, n_qp, 6, 3 n_loc)
        wgrad = g.grad * g.w[:, :, None, None]  # (k, n_qp, n_loc, 3)
        return (wgrad @ (e @ B)).sum(axis=1)  # (k, n_loc, 3 n_loc)

    shape = (mesh.n_nodes, 3 * mesh.n_nodes)
    return _assemble_forms(mesh, kernel, _order(mesh), mesh.cells, vector_dofs(mesh), shape, chunk)


def permittivity_matrix(mesh: Mesh3D, kappa: np.ndarray, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × N) ∫ κ∇φ·∇θ, κ a 3×3 symmetric positive definite matrix; `chunk` cells at a
    time."""
    kappa = _check_matrix("kappa", kappa, (3, 3))

    def kernel(g: Geometry3D) -> np.ndarray:
        wgrad = g.grad * g.w[:, :, None, None]  # (k, n_qp, n_loc, 3)
        return (wgrad @ kappa @ g.grad.transpose(0, 1, 3, 2)).sum(axis=1)  # (k, n_loc, n_loc)

    shape = (mesh.n_nodes, mesh.n_nodes)
    return _assemble_forms(mesh, kernel, _order(mesh), mesh.cells, mesh.cells, shape, chunk)


def piezo_matrix(mesh: Mesh3D, C: np.ndarray, e: np.ndarray, kappa: np.ndarray) -> sp.csr_matrix:
    """The coupled operator [[K, Gᵀ], [−G, P]] on (u interleaved, then φ): (4N × 4N)."""
    K = elasticity_matrix(mesh, C)
    G = coupling_matrix(mesh, e)
    P = permittivity_matrix(mesh, kappa)
    return sp.bmat([[K, G.T], [-G, P]], format="csr")


def mass_matrix(mesh: Mesh3D, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × N) ∫ φ θ (the L² Gram matrix); `chunk` cells at a time."""

    def kernel(g: Geometry3D) -> np.ndarray:
        return np.einsum("cq,qa,qb->cab", g.w, g.phi, g.phi, optimize=True)  # (k, n_loc, n_loc)

    order = 2 if mesh.cell_type == "tetra" else 4
    shape = (mesh.n_nodes, mesh.n_nodes)
    return _assemble_forms(mesh, kernel, order, mesh.cells, mesh.cells, shape, chunk)


def _evaluate(func: Func3, x: np.ndarray, ncomp: int) -> np.ndarray:
    """func at points x (..., 3) as an array x.shape[:-1] + (ncomp,)."""
    shape = x.shape[:-1] + (ncomp,)
    if callable(func):
        v = np.asarray(func(x[..., 0], x[..., 1], x[..., 2]), dtype=float)
        if ncomp == 1 and v.shape == x.shape[:-1]:
            v = v[..., None]
        ok = v.shape == shape or v.ndim == 0
    else:
        v = np.asarray(func, dtype=float)
        ok = v.size == ncomp and v.ndim <= 1
        v = v.reshape(-1)  # (ncomp,)
    if not ok:
        what = "function values" if callable(func) else "constant"
        raise ValueError(
            f"{what} of shape {v.shape} do not fit points {x.shape[:-1]}, ncomp={ncomp}"
        )
    return np.broadcast_to(v, shape)


def volume_load(mesh: Mesh3D, func: Func3, ncomp: int, order: int = 4) -> np.ndarray:
    """∫_Ω f·v dx as a vector of length ncomp·N (interleaved: dof ncomp·i + k)."""
    g = cell_geometry(mesh, order)
    f = _evaluate(func, g.x, ncomp)  # (n_cells, n_qp, ncomp)
    Fe = np.einsum("cq,qa,cqk->cak", g.w, g.phi, f, optimize=True)  # (n_cells, n_loc, ncomp)
    return _scatter(Fe, mesh.cells, mesh.n_nodes)


def face_geometry(
    mesh: Mesh3D, name: str, order: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Quadrature on the faces of boundary part `name` (bilinear quads or flat triangles).

    Returns x (n_f, n_qp, 3) points, w (n_f, n_qp) weights × surface element, phi (n_qp, k)
    face shape values and n (n_f, n_qp, 3) unit outward normals. KeyError for an unknown part.
    """
    if name not in mesh.boundaries:
        raise KeyError(
            f"unknown boundary {name!r}; this mesh has: {', '.join(sorted(mesh.boundaries))}"
        )
    ref = reference_element(FACE_TYPE[mesh.cell_type])
    pts, wts = ref.quadrature(order)  # (n_qp, 2), (n_qp,)
    F = mesh.points[mesh.boundaries[name]]  # (n_f, k, 3)
    phi = ref.values(pts)  # (n_qp, k)
    T = np.einsum("fai,qaj->fqij", F, ref.gradients(pts), optimize=True)  # (n_f, n_qp, 3, 2)
    N = np.cross(T[..., 0], T[..., 1])  # (n_f, n_qp, 3) ∂x/∂s × ∂x/∂t
    dA = np.linalg.norm(N, axis=-1)  # (n_f, n_qp)
    return phi @ F, wts[None, :] * dA, phi, N / dA[..., None]


def boundary_load(mesh: Mesh3D, name: str, func: Func3, ncomp: int, order: int = 4) -> np.ndarray:
    """∫_Γ f·v ds over boundary part `name` (a traction when ncomp = 3, a surface charge when 1).

    Same layout and `func` conventions as `volume_load`; KeyError for an unknown part.
    """
    x, w, phi, _ = face_geometry(mesh, name, order)
    f = _evaluate(func, x, ncomp)  # (n_f, n_qp, ncomp)
    Fe = np.einsum("fq,qa,fqk->fak", w, phi, f, optimize=True)  # (n_f, k, ncomp)
    return _scatter(Fe, mesh.boundaries[name], mesh.n_nodes)


def interpolate(mesh: Mesh3D, func: Func3, ncomp: int) -> np.ndarray:
    """Nodal interpolant: vector of length ncomp·N (interleaved)."""
    return np.array(_evaluate(func, mesh.points, ncomp)).ravel()


def cell_fields(
    mesh: Mesh3D,
    u: np.ndarray,
    phi: np.ndarray | None,
    C: np.ndarray,
    e: np.ndarray | None,
    kappa: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Stress σ = Cε(u) + eᵀ∇φ (n_cells, 6, Voigt) and electric displacement D = eε(u) − κ∇φ
    (n_cells, 3) at the cell centroids.

    With `phi` None (purely elastic body) σ = Cε(u), D = 0 and `e`, `kappa` are ignored.
    """
    C = _check_matrix("C", C, (6, 6))
    ref = reference_element3d(mesh.cell_type)
    check_cells(mesh)
    g = _geometry(mesh, ref.centroid[None, :], np.ones(1))
    grad = g.grad[:, 0]  # (n_cells, n_loc, 3)
    U = np.asarray(u, dtype=float).reshape(mesh.n_nodes, 3)[mesh.cells]  # (n_cells, n_loc, 3)
    eps = np.einsum("cIa,ca->cI", strain_operator(grad), U.reshape(mesh.n_cells, -1))  # (n_c, 6)
    sigma = eps @ C.T  # (n_cells, 6)
    if phi is None:
        return sigma, np.zeros((mesh.n_cells, 3))
    e = _check_matrix("e", e, (3, 6))
    kappa = _check_matrix("kappa", kappa, (3, 3))
    E = np.einsum("ca,cai->ci", np.asarray(phi, dtype=float)[mesh.cells], grad)  # (n_cells, 3)
    return sigma + E @ e, eps @ e.T - E @ kappa.T


def l2_error(mesh: Mesh3D, uh: np.ndarray, exact: Func3, ncomp: int, order: int = 4) -> float:
    """‖u − u_h‖_{L²(Ω)} by quadrature of `order` (uh interleaved, length ncomp·N)."""
    g = cell_geometry(mesh, order)
    U = np.asarray(uh, dtype=float).reshape(mesh.n_nodes, ncomp)[mesh.cells]  # (n_c, n_loc, nc)
    vh = np.einsum("qa,cak->cqk", g.phi, U, optimize=True)  # (n_cells, n_qp, ncomp)
    d = _evaluate(exact, g.x, ncomp) - vh  # (n_cells, n_qp, ncomp)
    return float(np.sqrt(np.einsum("cq,cqk,cqk->", g.w, d, d)))


def h1_seminorm_error(
    mesh: Mesh3D, uh: np.ndarray, grad_exact: Callable, ncomp: int, order: int = 4
) -> float:
    """|u − u_h|_{H¹(Ω)}; grad_exact(x, y, z) returns x.shape + (ncomp, 3) (or x.shape + (3,))."""
    g = cell_geometry(mesh, order)
    U = np.asarray(uh, dtype=float).reshape(mesh.n_nodes, ncomp)[mesh.cells]  # (n_c, n_loc, nc)
    Gh = np.einsum("cqai,cak->cqki", g.grad, U, optimize=True)  # (n_cells, n_qp, ncomp, 3)
    x = g.x[..., 0]  # (n_cells, n_qp)
    G = np.asarray(grad_exact(g.x[..., 0], g.x[..., 1], g.x[..., 2]), dtype=float)
    if ncomp == 1 and G.shape == x.shape + (3,):
        G = G[..., None, :]  # (n_cells, n_qp, 1, 3)
    if G.shape != x.shape + (ncomp, 3):
        raise ValueError(f"grad_exact returned shape {G.shape}, expected {x.shape + (ncomp, 3)}")
    d = G - Gh  # (n_cells, n_qp, ncomp, 3)
    return float(np.sqrt(np.einsum("cq,cqki,cqki->", g.w, d, d)))
