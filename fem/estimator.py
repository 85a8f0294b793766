"""Residual a posteriori error indicators of a linear flux F(∇U) on any `fem.mesh.Mesh`.

A system of c fields U (n_nodes, c) (displacement components, a potential) with the weak form
Σ ∫ F(∇U) : ∇V = ∫ f · V + ∫_Γ_N t · V, F linear: vec F = L vec ∇U, ∇U (c, d) flattened
row-major. Its residuals (Verfürth; for contact with mortar multipliers Wohlmuth, Hild and
Nicaise, Weiss and Wohlmuth) are

- in a cell T: h_T² ‖f + div F_h‖²_T (`volume_indicator`; div F_h = 0 on simplices, where ∇U_h
  is constant; on Q1 cells from the physical second derivatives, `divergence`),
- on an interior facet E: ½ h_E ‖[F_h n]‖²_E given to each of its two cells
  (`jump_indicator`),
- on a boundary facet: h_E ‖R‖²_E for a residual R of the flux there (Neumann data t − F_h n,
  a contact multiplier; `boundary_indicator`): `FacetFluxes` holds F_h n at quadrature points
  of every facet of every cell.

Everything is dimension-generic: cells of `fem.elements`, facets oriented outward by
`fem.elements.FACETS`. The two sides of an interior facet are evaluated at the same physical
points: the facet is parametrised from its sorted node list (line and triangle facets; a
quadrilateral facet of a hexahedron uses its centroid only).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .elements import FACET_TYPE, FACETS, reference_element
from .mesh import Mesh


def cell_diameters(mesh: Mesh) -> np.ndarray:
    """(n_cells,) h_T: the largest distance between two nodes of each cell."""
    P = mesh.points[mesh.cells]  # (n_cells, k, d)
    return np.linalg.norm(P[:, :, None, :] - P[:, None, :, :], axis=-1).max(axis=(1, 2))


def _gradients(mesh: Mesh, cells: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Physical shape gradients (n, q, n_loc, d) of cells `cells` (n,) at reference points
    `pts` (n, q, d), one set of points per cell."""
    ref = reference_element(mesh.cell_type)
    n, q, d = pts.shape
    dphi = ref.gradients(pts.reshape(-1, d)).reshape(n, q, ref.n_loc, d)  # (n, q, n_loc, d)
    X = mesh.points[mesh.cells[cells]]  # (n, n_loc, d)
    J = np.einsum("nai,nqaj->nqij", X, dphi)  # (n, q, d, d) ∂x_i/∂ξ_j
    return dphi @ np.linalg.inv(J)  # (n, q, n_loc, d) rows ∇_ξφᵀ J⁻¹


def fluxes(mesh: Mesh, U: np.ndarray, L: np.ndarray, cells: np.ndarray, pts: np.ndarray):
    """F_h (n, q, c, d) of the nodal fields U (n_nodes, c) in cells `cells` (n,) at reference
    points `pts` (n, q, d); L (c d, c d) maps vec ∇U to vec F."""
    grad = _gradients(mesh, cells, pts)  # (n, q, n_loc, d)
    G = np.einsum("nqai,nak->nqki", grad, U[mesh.cells[cells]])  # (n, q, c, d)
    n, q, c, d = G.shape
    return (G.reshape(n, q, c * d) @ L.T).reshape(n, q, c, d)


@dataclass(frozen=True, eq=False)
class FacetFluxes:
    """F_h n on every facet of every cell (an interior facet appears twice, once per cell).

    cell : (n_i,) the cell of each facet instance.
    facet : (n_i,) index of the facet (unique over the mesh; equal for the two instances of an
        interior facet).
    nodes : (n_i, k) the facet's nodes sorted increasingly (its key).
    x : (n_i, q, d) physical quadrature points, the same points for the two instances.
    w : (n_i, q) quadrature weights × facet measure.
    h : (n_i,) facet diameters h_E.
    normal : (n_i, q, d) the unit normal out of `cell`.
    flux : (n_i, q, c) F_h n out of `cell`.
    interior : (n_i,) bool, the facet has two cells.
    t : (q, d − 1) the facet rule's points in the facet's reference coordinates, taken along
        the sorted node list (a line: from `nodes[:, 0]` to `nodes[:, 1]`).
    """

    cell: np.ndarray
    facet: np.ndarray
    nodes: np.ndarray
    x: np.ndarray
    w: np.ndarray
    h: np.ndarray
    normal: np.ndarray
    flux: np.ndarray
    interior: np.ndarray
    t: np.ndarray

    def on(self, facets: np.ndarray) -> np.ndarray:
        """(n_b,) the instance of each boundary facet `facets` (n_b, k) (a mesh's boundary part);
        ValueError for a facet that is not a boundary facet of the mesh."""
        bnd = np.flatnonzero(~self.interior)
        index = {tuple(self.nodes[i]): i for i in bnd}
        keys = np.sort(facets, axis=1)
        missing = [tuple(k) for k in keys if tuple(k) not in index]
        if missing:
            raise ValueError(f"facets {missing[:3]} are not boundary facets of the mesh")
        return np.array([index[tuple(k)] for k in keys], dtype=int)


def facet_fluxes(mesh: Mesh, U: np.ndarray, L: np.ndarray, order: int = 2) -> FacetFluxes:
    """F_h n at the points of a facet rule of `order` on every facet of every cell (a
    quadrilateral facet: its centroid), U (n_nodes, c), L (c d, c d)."""
    ctype = mesh.cell_type
    ref = reference_element(ctype)
    ftype = FACET_TYPE[ctype]
    fref = reference_element(ftype)
    local = FACETS[ctype]  # (n_lf, k)
    n_lf, k = local.shape
    inst = mesh.cells[:, local].reshape(-1, k)  # (n_i, k) outward node order
    cell = np.repeat(np.arange(mesh.n_cells), n_lf)  # (n_i,)
    lf = np.tile(np.arange(n_lf), mesh.n_cells)  # (n_i,)
    order_ = np.argsort(inst, axis=1)  # (n_i, k)
    nodes = np.take_along_axis(inst, order_, axis=1)  # (n_i, k) sorted
    if float(mesh.n_nodes) ** k < 2.0**62:  # one int64 code per facet: a faster unique
        code = np.zeros(len(nodes), dtype=np.int64)  # (n_i,)
        for j in range(k):
            code = code * mesh.n_nodes + nodes[:, j]
        _, facet, count = np.unique(code, return_inverse=True, return_counts=True)
    else:
        _, facet, count = np.unique(nodes, axis=0, return_inverse=True, return_counts=True)
    facet = facet.ravel()
    if fref.simplex:
        t, wq = fref.quadrature(order)  # (q, d − 1), (q,)
        phi = fref.values(t)  # (q, k) barycentric in the sorted node order
        V = ref.vertices[local[lf]]  # (n_i, k, d) reference vertices, outward order
        V = np.take_along_axis(V, order_[:, :, None], axis=1)  # sorted node order
        pts = np.einsum("qa,nad->nqd", phi, V)  # (n_i, q, d)
    else:  # quadrilateral facets: the centroid
        t, wq = fref.centroid[None, :], np.ones(1)
        pts = ref.vertices[local[lf]].mean(axis=1)[:, None, :]  # (n_i, 1, d)
    if ref.simplex:  # ∇U_h is constant in a cell: one flux per cell, on each of its facets
        mid = np.broadcast_to(ref.vertices.mean(axis=0), (mesh.n_cells, 1, ref.dim))
        Fc = fluxes(mesh, U, L, np.arange(mesh.n_cells), mid)  # (n_cells, 1, c, d)
        F = np.broadcast_to(Fc[cell], (len(cell), pts.shape[1], *Fc.shape[2:]))  # (n_i, q, c, d)
    else:
        F = fluxes(mesh, U, L, cell, pts)  # (n_i, q, c, d)
    X = mesh.points[mesh.cells[cell]]  # (n_i, n_loc, d)
    x = np.einsum(
        "nqa,nad->nqd", ref.values(pts.reshape(-1, ref.dim)).reshape(*pts.shape[:2], -1), X
    )
    P = mesh.points[inst]  # (n_i, k, d) outward order
    if mesh.dim == 2:
        T = P[:, 1] - P[:, 0]  # (n_i, 2) domain on the left: outward = tangent turned right
        N = np.stack([T[:, 1], -T[:, 0]], axis=-1)  # (n_i, 2), length |E|
        measure = np.linalg.norm(N, axis=-1)
    else:
        N = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])  # (n_i, 3)
        measure = 0.5 * np.linalg.norm(N, axis=-1) * (1 if k == 3 else 2)
    normal = np.broadcast_to((N / np.linalg.norm(N, axis=-1)[:, None])[:, None], x.shape)
    h = np.linalg.norm(P[:, :, None] - P[:, None], axis=-1).max(axis=(1, 2))  # (n_i,)
    flux = np.einsum("nqcd,nqd->nqc", F, normal)  # (n_i, q, c)
    wts = wq[None, :] / wq.sum() * measure[:, None]  # (n_i, q)
    return FacetFluxes(cell, facet, nodes, x, wts, h, normal, flux, count[facet] == 2, t)


def jump_indicator(ff: FacetFluxes, n_cells: int, weight: np.ndarray | None = None) -> np.ndarray:
    """(n_cells,) ½ Σ_{interior E ⊂ ∂T} h_E ‖[F_h n]‖²_E, the components weighted by `weight`
    (c,) (default 1)."""
    inner = np.flatnonzero(ff.interior)
    idx = inner[np.argsort(ff.facet[inner], kind="stable")].reshape(-1, 2)  # (n_E, 2) pairs
    jump = ff.flux[idx[:, 0]] + ff.flux[idx[:, 1]]  # (n_E, q, c): normals are opposite
    wgt = np.ones(jump.shape[-1]) if weight is None else np.asarray(weight)
    per_facet = ff.h[idx[:, 0]] * np.einsum("eq,eqc,c->e", ff.w[idx[:, 0]], jump**2, wgt)
    out = np.zeros(n_cells)
    np.add.at(out, ff.cell[idx[:, 0]], 0.5 * per_facet)
    np.add.at(out, ff.cell[idx[:, 1]], 0.5 * per_facet)
    return out


def boundary_indicator(
    ff: FacetFluxes, instances: np.ndarray, residual: np.ndarray, n_cells: int
) -> np.ndarray:
    """(n_cells,) Σ h_E ‖R‖²_E over the facet instances `instances` (n_b,) with residual values
    R (n_b, q, c) at their quadrature points (already weighted per component)."""
    per_facet = ff.h[instances] * np.einsum("bq,bqc->b", ff.w[instances], residual**2)
    out = np.zeros(n_cells)
    np.add.at(out, ff.cell[instances], per_facet)
    return out


def _reference_hessians(cell_type: str, pts: np.ndarray) -> np.ndarray:
    """(q, n_loc, d, d) second derivatives ∂²φ_a/∂ξ_i∂ξ_j of the shape functions at `pts`
    (q, d): 0 on simplices; on tensor cells only i ≠ j, ½^d v_ai v_aj Π_{k≠i,j}(1 + ξ_k v_ak)."""
    ref = reference_element(cell_type)
    q, d = pts.shape
    H = np.zeros((q, ref.n_loc, d, d))
    if ref.simplex:
        return H
    V = ref.vertices  # (n_loc, d)
    f = 1 + pts[:, None, :] * V[None]  # (q, n_loc, d) the 1D factors
    for i in range(d):
        for j in range(d):
            if i != j:
                others = np.prod(np.delete(f, [i, j], axis=2), axis=2)  # (q, n_loc)
                H[:, :, i, j] = 0.5**d * V[:, i] * V[:, j] * others
    return H


def _map_hessians(Hr: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(n_cells, q, d, d, d) the reference Hessians H_ξ x_m of the cell maps, from the shape
    functions' Hr (q, n_loc, d, d) and the nodes X (n_cells, n_loc, d)."""
    return np.einsum("qaij,cam->cqmij", Hr, X)


def divergence(mesh: Mesh, U: np.ndarray, L: np.ndarray, order: int = 4):
    """div F_h (n_cells, q, c) at the points of a cell rule of `order`, with the physical
    points x (n_cells, q, d) and weights × det J (n_cells, q): 0 on simplices; on Q1 cells
    from the physical Hessians H = J⁻ᵀ(H_ξ U − Σ_m ∂_m U H_ξ x_m)J⁻¹."""
    ref = reference_element(mesh.cell_type)
    pts, wts = ref.quadrature(order)  # (q, d), (q,)
    X = mesh.points[mesh.cells]  # (n_cells, n_loc, d)
    x = np.einsum("qa,cad->cqd", ref.values(pts), X)  # (n_cells, q, d)
    J = ref.jacobians(X, pts)  # (n_cells, q, d, d)
    w = wts * np.abs(np.linalg.det(J))  # (n_cells, q)
    n, q, d = *x.shape[:2], mesh.dim
    c = U.shape[1]
    if ref.simplex:
        return np.zeros((n, q, c)), x, w
    Hr = _reference_hessians(mesh.cell_type, pts)  # (q, n_loc, d, d)
    Ue = U[mesh.cells]  # (n_cells, n_loc, c)
    Jinv = np.linalg.inv(J)  # (n_cells, q, d, d)
    grad = np.einsum("qai,cqij->cqaj", ref.gradients(pts), Jinv)  # (n_cells, q, n_loc, d)
    G = np.einsum("cqaj,cak->cqkj", grad, Ue)  # (n_cells, q, c, d) ∇U
    HU = np.einsum("qaij,cak->cqkij", Hr, Ue)  # (n_cells, q, c, d, d) reference Hessians of U
    HX = _map_hessians(Hr, X)  # (n_cells, q, d, d, d)
    HU = HU - np.einsum("cqkm,cqmij->cqkij", G, HX)
    Hx = np.einsum("cqai,cqkab,cqbj->cqkij", Jinv, HU, Jinv)  # (n_cells, q, c, d, d) physical
    Lr = L.reshape(c, d, c, d)  # F_kj = Σ L[k, j, l, i] ∂_i U_l
    return np.einsum("kjli,cqlij->cqk", Lr, Hx), x, w


def volume_indicator(
    mesh: Mesh,
    U: np.ndarray,
    L: np.ndarray,
    source: Callable[..., np.ndarray] | None,
    weight: np.ndarray,
    order: int = 4,
) -> np.ndarray:
    """(n_cells,) h_T² ‖f + div F_h‖²_T, the components weighted by `weight` (c,), for a source
    f(x, y[, z]) → (..., c) (None: f = 0)."""
    div, x, w = divergence(mesh, U, L, order)  # (n_cells, q, c)
    r = div
    if source is not None:
        f = np.asarray(source(*np.moveaxis(x, -1, 0)), dtype=float)
        r = r + np.broadcast_to(f.reshape(*x.shape[:2], -1), r.shape)
    return cell_diameters(mesh) ** 2 * np.einsum("cq,cqk,k->c", w, r**2, weight)


def energy_error(
    mesh: Mesh, U: np.ndarray, S: np.ndarray, grad_exact: Callable[..., np.ndarray], order: int = 4
) -> np.ndarray:
    """(n_cells,) ∫_T vec(∇e)ᵀ S vec(∇e), e = U_exact − U_h, S (c d, c d) symmetric positive
    semi-definite; grad_exact(x, y[, z]) → (..., c, d)."""
    ref = reference_element(mesh.cell_type)
    pts, wts = ref.quadrature(order)  # (q, d), (q,)
    cells = np.arange(mesh.n_cells)
    P = np.broadcast_to(pts, (mesh.n_cells, *pts.shape))  # (n_cells, q, d)
    grad = _gradients(mesh, cells, P)  # (n_cells, q, n_loc, d)
    Gh = np.einsum("nqai,nak->nqki", grad, U[mesh.cells])  # (n_cells, q, c, d)
    X = mesh.points[mesh.cells]
    x = np.einsum("qa,cad->cqd", ref.values(pts), X)  # (n_cells, q, d)
    detJ = np.abs(np.linalg.det(ref.jacobians(X, pts)))  # (n_cells, q)
    G = np.asarray(grad_exact(*np.moveaxis(x, -1, 0)), dtype=float).reshape(Gh.shape)
    E = (G - Gh).reshape(*Gh.shape[:2], -1)  # (n_cells, q, c d)
    return np.einsum("cq,cqi,ij,cqj->c", wts * detJ, E, S, E)
