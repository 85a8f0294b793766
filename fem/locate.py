"""Point location in a 2D or 3D P1/Q1 mesh: the cell that holds a point and the point's
reference coordinates in it, and a nodal P1/Q1 field evaluated at arbitrary points (the
transfer between the levels of a scene: the multigrid prolongation wherever the meshes are
nested, interpolation elsewhere).

A point is looked for in the cell with the nearest centroid, then, if it lies outside that
one by more than OUTSIDE_TOL, among the cells with the nearest centroids, then among every
cell whose centroid is close enough to hold it (`_search_ball`), by inverting the cell maps
(Newton; exact after one step for P1). A point outside every candidate (a refined curved
boundary's new node, which lies outside the coarse mesh) gets the candidate it is least
outside of, and the field there is extrapolated from that cell.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from fem.elements import reference_element
from fem.jacobians import solve2
from fem.mesh import Mesh

CHUNK = 32_768  # point-cell pairs inverted at once (memory: arrays of (CHUNK, n_loc, d) floats)
OUTSIDE_TOL = 1e-9  # reference coordinates: a point farther out of a cell is outside it
# cells with the nearest centroids tried for a point outside the nearest one, per dimension
CANDIDATES = {2: 8, 3: 12}
NEWTON_STEPS = 8  # at most, inverting a cell map (an affine cell: one step)
NEWTON_TOL = 1e-13  # reference coordinates: a Newton step this small has converged
MISS_TOL = 1e-9  # physical: an unconverged inversion this far off its point is not taken


def outside(cell_type: str, xi: np.ndarray) -> np.ndarray:
    """How far reference points xi (..., d) lie outside the reference cell (...,) (≤ 0
    inside): the simplex {ξ ≥ 0, Σξ ≤ 1} (triangle, tetra) or the box [−1, 1]^d (quad,
    hexahedron)."""
    if cell_type in ("triangle", "tetra"):
        return np.maximum(-xi.min(axis=-1), xi.sum(axis=-1) - 1.0)
    return np.abs(xi).max(axis=-1) - 1.0


def locate(
    mesh: Mesh, pts: np.ndarray, candidates: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cell (M,) and reference coordinates (M, d) of each point of `pts` (M, d) in
    `mesh`, and how far each lies outside that cell in reference coordinates (M,) (≤ 0
    inside: `outside`).

    A point is looked for in the cell with the nearest centroid, then, if it lies outside that
    one by more than OUTSIDE_TOL, among the `candidates` (default CANDIDATES of the mesh's
    dimension) cells with the nearest centroids, then among every cell close enough to hold
    it (`_search_ball`); a point outside all of those gets the one it is least outside of
    (extrapolation)."""
    d = mesh.points.shape[1]
    tree = cKDTree(mesh.points[mesh.cells].mean(axis=1))  # (n_cells, d) centroids
    cell = tree.query(pts, k=1)[1].astype(np.int64)  # (M,)
    xi = _invert(mesh, pts, cell[:, None])[:, 0]  # (M, d)
    out = outside(mesh.cell_type, xi)  # (M,)
    retry = np.flatnonzero(out > OUTSIDE_TOL)
    k = min(CANDIDATES[d] if candidates is None else candidates, mesh.n_cells)
    if retry.size and k > 1:
        cand = tree.query(pts[retry], k=k)[1].reshape(retry.size, k)  # (M_r, k)
        xr = _invert(mesh, pts[retry], cand)  # (M_r, k, d)
        outr = outside(mesh.cell_type, xr)  # (M_r, k)
        best = np.argmin(outr, axis=1)  # (M_r,)
        rows = np.arange(retry.size)
        cell[retry], xi[retry], out[retry] = cand[rows, best], xr[rows, best], outr[rows, best]
    retry = np.flatnonzero(out > OUTSIDE_TOL)
    if retry.size:
        _search_ball(mesh, tree, pts, retry, cell, xi, out)
    return cell, xi, out


def _search_ball(
    mesh: Mesh,
    tree: cKDTree,
    pts: np.ndarray,
    retry: np.ndarray,
    cell: np.ndarray,
    xi: np.ndarray,
    out: np.ndarray,
) -> None:
    """For the points `retry` outside their nearest cells: every cell that can hold them, in
    place of (cell, xi, out) where one holds them better. A cell holds only points within its
    radius (the largest distance of a vertex from its centroid) of its centroid, so the cells
    whose centroids lie within the largest radius R of the point are all that can: a point
    inside the mesh is found whatever the grading (the nearest centroids are not enough where
    cells of different sizes meet: a graded mesh of 12 triangles put 1 of 200 random points in
    the wrong cell with 8 candidates). A point outside every cell (a refined curved boundary's
    new node) keeps the candidate it is least outside of among them."""
    X = mesh.points[mesh.cells]  # (n_cells, n_loc, d)
    R = float(np.linalg.norm(X - X.mean(axis=1, keepdims=True), axis=2).max())
    near = tree.query_ball_point(pts[retry], R * (1 + 1e-9) + 1e-300)  # (M_r,) lists
    sizes = np.fromiter((len(c) for c in near), dtype=np.int64, count=retry.size)  # (M_r,)
    if sizes.sum() == 0:
        return
    owner = np.repeat(np.arange(retry.size), sizes)  # (P,) the point of each pair
    cand = np.fromiter((j for c in near for j in c), dtype=np.int64, count=int(sizes.sum()))
    xr = _invert(mesh, pts[retry][owner], cand[:, None])[:, 0]  # (P, d)
    outr = outside(mesh.cell_type, xr)  # (P,)
    order = np.lexsort((outr, owner))  # by point, least outside first
    has = np.flatnonzero(sizes)  # (M_h,) the points with a cell in reach (others keep theirs)
    first = order[np.searchsorted(owner[order], has)]  # (M_h,) each one's best pair
    better = outr[first] < out[retry[has]]  # (M_h,)
    idx, pick = retry[has[better]], first[better]
    cell[idx], xi[idx], out[idx] = cand[pick], xr[pick], outr[pick]


def _invert(mesh: Mesh, pts: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """Reference coordinates (M, k, d) of the points `pts` (M, d) in each of their candidate
    cells `cand` (M, k): Newton on the cell map, CHUNK point-cell pairs at a time, each pair
    until its step is below NEWTON_TOL (an affine cell: one step; the pairs still iterating
    are the only ones computed on). A pair whose Jacobian is singular, or whose Newton stops
    after NEWTON_STEPS with its image off the point (`_misses`), gets inf (outside).

    Why written out: the sums over the n_loc nodes as vector operations and the 2 × 2 solves by
    Cramer's rule, where einsum and a batched LAPACK solve took 70 % of the nested warm
    start's point location (paper scene, level 5 located in level 4: 1.05 s CPU)."""
    ref = reference_element(mesh.cell_type)
    M, k = cand.shape
    d = pts.shape[1]
    xi = np.empty((M, k, d))
    step = max(1, CHUNK // k)
    for lo in range(0, M, step):
        c = cand[lo : lo + step].reshape(-1)  # (c k,)
        p = np.repeat(pts[lo : lo + step], k, axis=0)  # (c k, d)
        X = mesh.points[mesh.cells[c]]  # (c k, n_loc, d)
        x = np.broadcast_to(ref.centroid, p.shape).copy()  # (c k, d)
        act = np.arange(x.shape[0])  # (a,) the pairs still iterating
        for _ in range(NEWTON_STEPS):
            Xa, xa = X[act], x[act]  # (a, n_loc, d), (a, d)
            phi, dphi = ref.values(xa), ref.gradients(xa)  # (a, n_loc), (a, n_loc, d)
            r = -p[act]  # (a, d) x(ξ) − p
            J = np.zeros((act.size, d, d))  # (a, d, d) ∂x_i/∂ξ_j
            for n in range(Xa.shape[1]):
                r += phi[:, n, None] * Xa[:, n]
                J += Xa[:, n, :, None] * dphi[:, n, None, :]
            dx = _solve_small(J, r)  # (a, d)
            x[act] = xa - dx
            act = act[~(np.abs(dx).max(axis=1) < NEWTON_TOL)]  # NaN (singular) stops too
            if act.size == 0:
                break
        if act.size:  # not converged: a point off a non-affine cell may stall inside [-1, 1]^d
            x[act[_misses(ref, X[act], x[act], p[act])]] = np.inf
        x[~np.isfinite(x).all(axis=1)] = np.inf
        xi[lo : lo + step] = x.reshape(-1, k, d)
    return xi


def _misses(ref, X: np.ndarray, xi: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(a,) bool: the reference points xi (a, d) of cells X (a, n_loc, d) whose image misses
    p (a, d) by more than MISS_TOL × (the cell's extent + the point's distance from its
    centroid): Newton stopped without converging, the point is not where xi says. (A point far
    outside an affine cell converges to rounding relative to that distance, not to NEWTON_TOL.)"""
    r = np.einsum("an,and->ad", ref.values(xi), X) - p  # (a, d)
    scale = np.ptp(X, axis=1).max(axis=1) + np.linalg.norm(p - X.mean(axis=1), axis=1)  # (a,)
    return ~(np.linalg.norm(r, axis=1) <= MISS_TOL * scale)


def _solve_small(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """J⁻¹ r (a, d) for the matrices J (a, d, d): Cramer's rule for d = 2 (NaN where singular),
    LAPACK otherwise (a singular J gives NaN rows)."""
    if J.shape[1] == 2:
        return solve2(J, r)
    det = np.linalg.det(J)  # (a,)
    out = np.full(r.shape, np.nan)
    ok = det != 0
    out[ok] = np.linalg.solve(J[ok], r[ok, :, None])[:, :, 0]
    return out


def interpolate(mesh: Mesh, nodal: np.ndarray, cell: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """(M, c): the P1/Q1 function with nodal values `nodal` (N, c) or (N,) at the reference
    points xi (M, d) of the cells `cell` (M,)."""
    phi = reference_element(mesh.cell_type).values(xi)  # (M, n_loc)
    vals = np.asarray(nodal, dtype=float).reshape(mesh.n_nodes, -1)[mesh.cells[cell]]
    return np.einsum("ma,mac->mc", phi, vals)  # (M, c)


def evaluate(
    mesh: Mesh, nodal: np.ndarray, pts: np.ndarray, candidates: int | None = None
) -> np.ndarray:
    """The P1/Q1 function with nodal values `nodal` (N, c) or (N,) at the points `pts`
    (M, d): (M, c); a point outside the mesh is extrapolated from the cell `locate` gives it."""
    cell, xi, _ = locate(mesh, pts, candidates)
    return interpolate(mesh, nodal, cell, xi)
