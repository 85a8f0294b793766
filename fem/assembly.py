"""Vectorised (over cells) assembly of P1/Q1 forms, loads, post-processing and error norms in
2D and 3D: the dimension d, the reference element and its quadrature come from the mesh's cell
type (`fem.elements`).

Matrices are assembled in chunks of at most `CHUNK` cells (fewer where a cell's local
matrices per quadrature point are large: `LOCAL_ENTRIES`): the quadrature data and local matrices of
one chunk, not of the whole mesh, are alive at a time, and their values are summed into the
matrix's final sparsity pattern (built first from the cells' dof pairs, so it is the same
whatever the chunk size: explicit zeros where entries cancel are kept). Computed for all cells
at once, the 3D elasticity matrix's were the peak of a 3D solve with AMG (3,456 B per
tetrahedron: bracket3d level 2, 406 MiB against the AMG set-up's 246 MiB). The cells are
checked once, before the first chunk (`check_cells`).

Dof numbering: displacement component k of node i is dof d i + k; scalar fields (the electric
potential) have dof = node index. Voigt order (xx, yy, xy) in 2D, (xx, yy, zz, yz, xz, xy) in
3D (`VOIGT`, see `fem.tensors`), with engineering shear strains γ_ij = 2 ε_ij. Sign
convention of the paper: σ = C ε(u) + eᵀ∇φ, D = e ε(u) − κ∇φ; the coupled operator is
[[K, Gᵀ], [−G, P]].

Functions `func` given to loads, interpolation and error norms are called as func(x, y) (2D) or
func(x, y, z) (3D) with arrays of any shape and return x.shape + (ncomp,) (or x.shape when
ncomp = 1); a constant (float or length-ncomp sequence) may be given instead.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .elements import reference_element
from .facets import facet_quadrature
from .jacobians import CHUNK, check_cells, cofactors, determinants
from .mesh import Mesh
from .tensors import VOIGT_PAIRS

# a chunk's kernels hold a few arrays of (k, n_qp, r, c) entries (per quadrature point, before
# the sum over points): k is bounded so that one holds at most this many (16 MiB of float64).
# CHUNK cells alone left them at 75 MiB for hexahedra (8 points, 24 dofs), the whole peak of
# the build of block3d level 2 (142 MiB above the imports with 2,048 cells in one chunk)
LOCAL_ENTRIES = 2**21

Func = Callable[..., np.ndarray] | float | Sequence[float]

# Voigt index I -> tensor index pair (i, j), by dimension
VOIGT: dict[int, np.ndarray] = {2: np.array([[0, 0], [1, 1], [0, 1]]), 3: VOIGT_PAIRS}


@dataclass(frozen=True, eq=False)
class Geometry:
    """Quadrature data of cells.

    x : (n_cells, n_qp, d) physical quadrature points.
    w : (n_cells, n_qp) quadrature weights × det J.
    phi : (n_qp, n_loc) shape function values.
    grad : (n_cells, n_qp, n_loc, d) physical shape function gradients.
    """

    x: np.ndarray
    w: np.ndarray
    phi: np.ndarray
    grad: np.ndarray


def _geometry(
    mesh: Mesh, pts: np.ndarray, wts: np.ndarray, cells: slice | np.ndarray = slice(None)
) -> Geometry:
    """Quadrature data of the cells mesh.cells[cells] (a slice or indices), not checked for
    inversion."""
    ref = reference_element(mesh.cell_type)
    X = mesh.points[mesh.cells[cells]]  # (n_cells, n_loc, d)
    phi = ref.values(pts)  # (n_qp, n_loc)
    dphi = ref.gradients(pts)  # (n_qp, n_loc, d)
    # J is constant on a simplex: computed once per cell
    J = ref.jacobians(X, pts[:1] if ref.simplex else pts)  # (n_cells, n_J, d, d) ∂x_i/∂ξ_j
    cof = cofactors(J)  # (n_cells, n_J, d, d)
    detJ = determinants(J, cof)  # (n_cells, n_J)
    invJ = np.divide(cof.transpose(0, 1, 3, 2), detJ[..., None, None], order="C")  # (…, d, d)
    grad = dphi @ invJ  # (n_cells, n_qp, n_loc, d) ∇φ = J⁻ᵀ ∇_ξ φ (as rows: ∇_ξφᵀ J⁻¹)
    x = phi @ X  # (n_cells, n_qp, d)
    w = wts[None, :] * detJ  # (n_cells, n_qp)
    return Geometry(x=x, w=w, phi=phi, grad=grad)


def cell_geometry(mesh: Mesh, order: int = 2) -> Geometry:
    """Quadrature points, weights, shape values and physical gradients for a rule of `order`.

    Raises ValueError naming the first inverted or degenerate cell (`check_cells`).
    """
    check_cells(mesh)
    pts, wts = reference_element(mesh.cell_type).quadrature(order)
    return _geometry(mesh, pts, wts)


def vector_dofs(mesh: Mesh) -> np.ndarray:
    """(n_cells, d n_loc) global dofs d i + k, local order d a + k."""
    d = mesh.points.shape[1]
    return (d * mesh.cells[:, :, None] + np.arange(d)).reshape(mesh.n_cells, -1)


def _keys(rows: np.ndarray, cols: np.ndarray, ncol: int) -> np.ndarray:
    """(k, r, c) flat positions row · ncol + col of the local entries of k cells."""
    return rows[:, :, None].astype(np.int64) * ncol + cols[:, None, :]


def _pattern(
    rows: np.ndarray, cols: np.ndarray, shape, chunk: int, keep: np.ndarray | None = None
) -> sp.csr_matrix:
    """The sparsity pattern (sorted csr, int8 ones) of all cells' (rows, cols) dof pairs (those
    in rows where `keep` (shape[0],) holds, if given)."""
    P = sp.csr_matrix(shape, dtype=np.float32)
    for lo in range(0, rows.shape[0], chunk):
        R, C = rows[lo : lo + chunk], cols[lo : lo + chunk]  # (k, r), (k, c)
        k = _keys(R, C, shape[1])  # (k, r, c)
        k = (k if keep is None else k[keep[R]]).ravel()  # (k r c,) or the kept rows' entries
        one = np.ones(k.size, dtype=np.float32)  # positive: no cancellation in the sum
        P = P + sp.csr_matrix((one, (k // shape[1], k % shape[1])), shape=shape)
    P.sort_indices()
    return P


def touching(rows: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(k,) increasing: the cells with a dof among the rows where `keep` holds (rows
    (n_cells, r) the cells' row dofs, keep (n_rows,) bool): the cells an owned-rows assembly
    sums."""
    return np.flatnonzero(keep[rows].any(axis=1))


def _assemble_chunks(
    local_of: Callable[[slice | np.ndarray], np.ndarray],
    rows: np.ndarray,
    cols: np.ndarray,
    shape: tuple[int, int],
    chunk: int = CHUNK,
    keep: np.ndarray | None = None,
) -> sp.csr_matrix:
    """Σ over cells of the local matrices local_of(cells) (k, r, c) of each chunk `cells` of k
    cells, at the dofs rows (n_cells, r) × cols (n_cells, c), summed into the final pattern.

    keep : (shape[0],) bool or None. Given, only the rows where it holds are assembled (the
    others empty), from the cells touching them only (`touching`, in increasing order): each
    entry of those rows receives the same terms in the same order as in the whole assembly
    (`np.add.at` sums in cell order), so the rows are the whole matrix's bit for bit, pattern
    included, with no other row computed (a rank's owned rows: docs/distributed.md)."""
    if chunk < 1:
        raise ValueError(f"chunk must be ≥ 1 cell, got {chunk}")
    cells_of = None if keep is None else touching(rows, keep)  # (k_c,) increasing
    if cells_of is not None:
        rows, cols = rows[cells_of], cols[cells_of]  # (k_c, r), (k_c, c)
    P = _pattern(rows, cols, shape, chunk, keep)
    keys = np.repeat(np.arange(shape[0], dtype=np.int64), np.diff(P.indptr))  # (nnz,)
    keys *= shape[1]
    keys += P.indices  # (nnz,) increasing (sorted csr)
    data = np.zeros(P.nnz)  # (nnz,)
    for lo in range(0, rows.shape[0], chunk):
        cells = slice(lo, lo + chunk)
        local = local_of(cells if cells_of is None else cells_of[cells])  # (k, r, c)
        pos = np.searchsorted(keys, _keys(rows[cells], cols[cells], shape[1]))  # (k, r, c)
        if keep is None:
            np.add.at(data, pos.ravel(), local.ravel())
        else:  # the kept rows' entries, in the same (cell, r, c) order
            mine = keep[rows[cells]]  # (k, r)
            np.add.at(data, pos[mine].ravel(), local[mine].ravel())
    del keys
    return sp.csr_matrix((data, P.indices, P.indptr), shape=shape)


def _assemble_forms(
    mesh: Mesh,
    kernel: Callable[[Geometry], np.ndarray],
    rows: np.ndarray,
    cols: np.ndarray,
    shape: tuple[int, int],
    chunk: int,
    keep: np.ndarray | None = None,
    order: int | None = None,
) -> sp.csr_matrix:
    """Σ over cells of kernel(g) (k, r, c), g the quadrature data (rule of `order`, default
    the element's `form_order`) of a chunk of k cells, computed chunk by chunk; the cells are
    checked once first (`check_cells`). keep: only those rows, from the cells touching them
    (`_assemble_chunks`)."""
    check_cells(mesh)
    ref = reference_element(mesh.cell_type)
    pts, wts = ref.quadrature(ref.form_order if order is None else order)
    per_cell = wts.size * rows.shape[1] * cols.shape[1]  # entries of a cell's (n_qp, r, c)
    chunk = min(chunk, max(1, LOCAL_ENTRIES // per_cell))  # chunk < 1 is refused below
    return _assemble_chunks(
        lambda cells: kernel(_geometry(mesh, pts, wts, cells)), rows, cols, shape, chunk, keep
    )


def _sum_points(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """(k, r, c) Σ_q left[:, q] @ right[:, q] of left (k, n_qp, r, s) and right (k, n_qp, s, c),
    summed point after point in the order of `(left @ right).sum(axis=1)` (the same values, bit
    for bit) without its (k, n_qp, r, c) array: two (k, r, c) arrays at a time instead."""
    out = left[:, 0] @ right[:, 0]  # (k, r, c)
    for q in range(1, left.shape[1]):
        out += left[:, q] @ right[:, q]
    return out


def strain_operator(grad: np.ndarray) -> np.ndarray:
    """Voigt strain-displacement matrices B: (..., v, d n_loc) from gradients (..., n_loc, d),
    v = 3 (d = 2) or 6 (d = 3), local dof d a + k.

    Row I = (i, j) of `VOIGT[d]`: ε_ii = ∂_i u_i, γ_ij = ∂_j u_i + ∂_i u_j (i ≠ j).
    """
    *lead, n_loc, d = grad.shape
    pairs = VOIGT[d]  # (v, 2)
    B = np.zeros((*lead, len(pairs), n_loc, d))  # (..., v, n_loc, d)
    for row, (i, j) in enumerate(pairs):
        B[..., row, :, i] = grad[..., j]
        if i != j:
            B[..., row, :, j] = grad[..., i]
    return B.reshape(*lead, len(pairs), d * n_loc)


def _check_matrix(name: str, M: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    M = np.asarray(M, dtype=float)
    if M.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {M.shape}")
    return M


def _sizes(mesh: Mesh) -> tuple[int, int]:
    """(d, v): the dimension and the Voigt size d(d + 1)/2."""
    d = mesh.points.shape[1]
    return d, d * (d + 1) // 2


def elasticity_matrix(
    mesh: Mesh, C: np.ndarray, chunk: int = CHUNK, rows: np.ndarray | None = None
) -> sp.csr_matrix:
    """(dN × dN) ∫ C ε(u)·ε(v), C the v×v Voigt matrix; `chunk` cells at a time. rows (dN,)
    bool: only those rows (the others empty), bit for bit the whole matrix's, from the cells
    touching them (`_assemble_chunks`)."""
    d, v = _sizes(mesh)
    C = _check_matrix("C", C, (v, v))

    def kernel(g: Geometry) -> np.ndarray:
        B = strain_operator(g.grad)  # (k, n_qp, v, d n_loc)
        wBt = (B * g.w[:, :, None, None]).transpose(0, 1, 3, 2)  # (k, n_qp, d n_loc, v)
        return _sum_points(wBt, C @ B)  # (k, d n_loc, d n_loc)

    dofs = vector_dofs(mesh)  # (n_cells, d n_loc)
    n = d * mesh.n_nodes
    return _assemble_forms(mesh, kernel, dofs, dofs, (n, n), chunk, rows)


def coupling_matrix(
    mesh: Mesh,
    e: np.ndarray,
    chunk: int = CHUNK,
    rows: np.ndarray | None = None,
    transposed: bool = False,
) -> sp.csr_matrix:
    """(N × dN) G[θ, u] = ∫ ∇θ · (e ε(u)), e the d×v piezoelectric matrix (rows D_x, D_y(, D_z));
    `chunk` cells at a time. rows (N,) bool: only those rows (`elasticity_matrix`).
    transposed: Gᵀ (dN × N) assembled as such, each entry the same terms in the same cell order
    as G's, so that its rows where `rows` (dN,) holds are G.T's bit for bit without G's other
    columns."""
    d, v = _sizes(mesh)
    e = _check_matrix("e", e, (d, v))

    def kernel(g: Geometry) -> np.ndarray:
        B = strain_operator(g.grad)  # (k, n_qp, v, d n_loc)
        wgrad = g.grad * g.w[:, :, None, None]  # (k, n_qp, n_loc, d)
        G = _sum_points(wgrad, e @ B)  # (k, n_loc, d n_loc)
        return G.transpose(0, 2, 1) if transposed else G

    dofs = (mesh.cells, vector_dofs(mesh))  # G's rows (n_cells, n_loc), columns (n_cells, d n_loc)
    shape = (mesh.n_nodes, d * mesh.n_nodes)
    if transposed:
        dofs, shape = dofs[::-1], shape[::-1]
    return _assemble_forms(mesh, kernel, *dofs, shape, chunk, rows)


def permittivity_matrix(
    mesh: Mesh, kappa: np.ndarray, chunk: int = CHUNK, rows: np.ndarray | None = None
) -> sp.csr_matrix:
    """(N × N) ∫ κ∇φ·∇θ, κ a d×d symmetric positive definite matrix; `chunk` cells at a time.
    rows (N,) bool: only those rows (`elasticity_matrix`)."""
    d, _ = _sizes(mesh)
    kappa = _check_matrix("kappa", kappa, (d, d))

    def kernel(g: Geometry) -> np.ndarray:
        wgrad = g.grad * g.w[:, :, None, None]  # (k, n_qp, n_loc, d)
        return _sum_points(wgrad @ kappa, g.grad.transpose(0, 1, 3, 2))  # (k, n_loc, n_loc)

    shape = (mesh.n_nodes, mesh.n_nodes)
    return _assemble_forms(mesh, kernel, mesh.cells, mesh.cells, shape, chunk, rows)


def stiffness_matrix(mesh: Mesh, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × N) ∫ ∇φ·∇θ (the H¹ seminorm Gram matrix)."""
    return permittivity_matrix(mesh, np.eye(mesh.points.shape[1]), chunk)


def piezo_matrix(
    mesh: Mesh, C: np.ndarray, e: np.ndarray, kappa: np.ndarray, rows: np.ndarray | None = None
) -> sp.csr_matrix:
    """The coupled operator [[K, Gᵀ], [−G, P]] on (u interleaved, then φ): ((d+1)N × (d+1)N).
    rows ((d+1)N,) bool: only those rows, from the cells touching them (`elasticity_matrix`;
    Gᵀ's assembled as such, `coupling_matrix`), each row's entries in the whole matrix's order."""
    if rows is None:
        K = elasticity_matrix(mesh, C)
        G = coupling_matrix(mesh, e)
        P = permittivity_matrix(mesh, kappa)
        return sp.bmat([[K, G.T], [-G, P]], format="csr")
    n_u = mesh.points.shape[1] * mesh.n_nodes
    r_u, r_phi = rows[:n_u], rows[n_u:]  # (dN,), (N,)
    K = elasticity_matrix(mesh, C, rows=r_u)
    Gt = coupling_matrix(mesh, e, rows=r_u, transposed=True)  # (dN, N) Gᵀ's rows r_u
    G = coupling_matrix(mesh, e, rows=r_phi)
    P = permittivity_matrix(mesh, kappa, rows=r_phi)
    return sp.bmat([[K, Gt], [-G, P]], format="csr")


def mass_matrix(mesh: Mesh, chunk: int = CHUNK) -> sp.csr_matrix:
    """(N × N) ∫ φ θ (the L² Gram matrix); `chunk` cells at a time."""

    def kernel(g: Geometry) -> np.ndarray:
        return np.einsum("cq,qa,qb->cab", g.w, g.phi, g.phi, optimize=True)  # (k, n_loc, n_loc)

    shape, order = (mesh.n_nodes, mesh.n_nodes), reference_element(mesh.cell_type).mass_order
    return _assemble_forms(mesh, kernel, mesh.cells, mesh.cells, shape, chunk, order=order)


def _evaluate(func: Func, x: np.ndarray, ncomp: int) -> np.ndarray:
    """func at points x (..., d) as an array x.shape[:-1] + (ncomp,)."""
    shape = x.shape[:-1] + (ncomp,)
    if callable(func):
        v = np.asarray(func(*np.moveaxis(x, -1, 0)), dtype=float)
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


def _scatter(local: np.ndarray, nodes: np.ndarray, n_nodes: int) -> np.ndarray:
    """Sum local nodal vectors (n_items, n_loc, ncomp) into the interleaved global vector."""
    ncomp = local.shape[-1]
    dofs = ncomp * nodes[:, :, None] + np.arange(ncomp)  # (n_items, n_loc, ncomp)
    return np.bincount(dofs.ravel(), weights=local.ravel(), minlength=ncomp * n_nodes)


def volume_load(mesh: Mesh, func: Func, ncomp: int, order: int = 4) -> np.ndarray:
    """∫_Ω f·v dx as a vector of length ncomp·N (interleaved: dof ncomp·i + k)."""
    g = cell_geometry(mesh, order)
    f = _evaluate(func, g.x, ncomp)  # (n_cells, n_qp, ncomp)
    Fe = np.einsum("cq,qa,cqk->cak", g.w, g.phi, f, optimize=True)  # (n_cells, n_loc, ncomp)
    return _scatter(Fe, mesh.cells, mesh.n_nodes)


def facet_geometry(
    mesh: Mesh, name: str, order: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Quadrature on the facets of boundary part `name`: straight edges (2D), flat triangles or
    bilinear quadrilaterals (3D).

    Returns x (n_f, n_qp, d) points, w (n_f, n_qp) weights × facet measure, phi (n_qp, k) facet
    shape values and n (n_f, n_qp, d) unit outward normals. KeyError for an unknown part.
    """
    ftype = reference_element(mesh.cell_type).facet_type
    x, wts, N, phi = facet_quadrature(mesh.points[mesh.boundary(name)], ftype, order)
    dA = np.linalg.norm(N, axis=-1)  # (n_f, n_qp)
    return x, wts[None, :] * dA, phi, N / dA[..., None]


def boundary_load(mesh: Mesh, name: str, func: Func, ncomp: int, order: int = 4) -> np.ndarray:
    """∫_Γ f·v ds over boundary part `name` (a traction when ncomp = d, a surface charge when 1).

    Same layout and `func` conventions as `volume_load`; KeyError for an unknown part.
    """
    x, w, phi, _ = facet_geometry(mesh, name, order)
    f = _evaluate(func, x, ncomp)  # (n_f, n_qp, ncomp)
    Fe = np.einsum("fq,qa,fqk->fak", w, phi, f, optimize=True)  # (n_f, k, ncomp)
    return _scatter(Fe, mesh.boundaries[name], mesh.n_nodes)


def interpolate(mesh: Mesh, func: Func, ncomp: int) -> np.ndarray:
    """Nodal interpolant: vector of length ncomp·N (interleaved)."""
    return np.array(_evaluate(func, mesh.points, ncomp)).ravel()


def cell_gradients(
    mesh: Mesh, u: np.ndarray, phi: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """Strain ε(u) in Voigt order (n_cells, v) and ∇φ (n_cells, d) (None if `phi` is None) at
    the cell centroids."""
    check_cells(mesh)
    ref = reference_element(mesh.cell_type)
    grad = _geometry(mesh, ref.centroid[None, :], np.ones(1)).grad[:, 0]  # (n_cells, n_loc, d)
    U = np.asarray(u, dtype=float).reshape(mesh.n_nodes, ref.dim)[mesh.cells]  # (nc, n_loc, d)
    eps = np.einsum("cIa,ca->cI", strain_operator(grad), U.reshape(mesh.n_cells, -1))  # (nc, v)
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
    """Stress σ = Cε(u) + eᵀ∇φ (n_cells, v, Voigt) and electric displacement D = eε(u) − κ∇φ
    (n_cells, d) at the cell centroids.

    With `phi` None (purely elastic body) σ = Cε(u), D = 0 and `e`, `kappa` are ignored.
    """
    d, v = _sizes(mesh)
    C = _check_matrix("C", C, (v, v))
    eps, E = cell_gradients(mesh, u, phi)  # (n_cells, v), (n_cells, d) ∇φ
    sigma = eps @ C.T  # (n_cells, v)
    if phi is None:
        return sigma, np.zeros((mesh.n_cells, d))
    e = _check_matrix("e", e, (d, v))
    kappa = _check_matrix("kappa", kappa, (d, d))
    return sigma + E @ e, eps @ e.T - E @ kappa.T


def l2_error(mesh: Mesh, uh: np.ndarray, exact: Func, ncomp: int, order: int = 4) -> float:
    """‖u − u_h‖_{L²(Ω)} by quadrature of `order` (uh interleaved, length ncomp·N)."""
    g = cell_geometry(mesh, order)
    U = np.asarray(uh, dtype=float).reshape(mesh.n_nodes, ncomp)[mesh.cells]  # (n_c, n_loc, nc)
    vh = np.einsum("qa,cak->cqk", g.phi, U, optimize=True)  # (n_cells, n_qp, ncomp)
    diff = _evaluate(exact, g.x, ncomp) - vh  # (n_cells, n_qp, ncomp)
    return float(np.sqrt(np.einsum("cq,cqk,cqk->", g.w, diff, diff)))


def h1_seminorm_error(
    mesh: Mesh, uh: np.ndarray, grad_exact: Callable, ncomp: int, order: int = 4
) -> float:
    """|u − u_h|_{H¹(Ω)}; grad_exact(x, y(, z)) returns x.shape + (ncomp, d) (or x.shape + (d,)
    when ncomp = 1)."""
    g = cell_geometry(mesh, order)
    d = mesh.points.shape[1]
    U = np.asarray(uh, dtype=float).reshape(mesh.n_nodes, ncomp)[mesh.cells]  # (n_c, n_loc, nc)
    Gh = np.einsum("cqai,cak->cqki", g.grad, U, optimize=True)  # (n_cells, n_qp, ncomp, d)
    x = g.x[..., 0]  # (n_cells, n_qp)
    G = np.asarray(grad_exact(*np.moveaxis(g.x, -1, 0)), dtype=float)  # (n_c, n_qp, ncomp, d)
    if ncomp == 1 and G.shape == x.shape + (d,):
        G = G[..., None, :]  # (n_cells, n_qp, 1, d)
    if G.shape != x.shape + (ncomp, d):
        raise ValueError(f"grad_exact returned shape {G.shape}, expected {x.shape + (ncomp, d)}")
    diff = G - Gh  # (n_cells, n_qp, ncomp, d)
    return float(np.sqrt(np.einsum("cq,cqki,cqki->", g.w, diff, diff)))
