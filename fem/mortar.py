"""Dual mortar coupling of two non-matching boundary traces in 2D (segment-to-segment).

The multiplier space lives on the SLAVE part: λ_h = Σ_i λ_i ψ_i with the dual basis ψ_i of
`fem.boundary.dual_basis_on_segment`, so the slave block is (block) diagonal. For displacements
u_s (slave trace nodes) and u_m (master trace nodes) the weak coupling ∫_Γ λ (u_s − u_m ∘ π) is

    B u = Ds u_s − M[active] u_m,    Ds[i, j] = ∫_Γ ψ̃_i φ_j^s,   M[i, j] = ∫_Γ ψ̃_i (φ_j^m ∘ π),

integrated over the slave polyline Γ; π maps a slave point x(t) to the master polyline along the
interpolated slave normal n(t) = (1 − t) n_a + t n_b (Puso/Popp). Master nodes are projected onto
each slave segment the same way (a quadratic in t), which cuts every slave segment into pieces
covered by one master segment each; each piece gets Gauss–Legendre quadrature.

ends="keep": ψ̃_i = ψ_i for all slave nodes, Ds = diag(D), D = trace weights ∫φ_i.
ends="merge" (Wohlmuth; as in 4C/MOOSE): the two end nodes of the slave part carry no
multiplier; on each end segment the end node's dual function is added to its neighbour's,
ψ̃_nb = ψ_nb + ψ_end = 1 there. Then Ds is no longer diagonal: Ds[nb, end] = ∫_end-seg φ_end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .boundary import dual_basis_on_segment, trace
from .mesh import Mesh


@dataclass(frozen=True, eq=False)
class Mortar:
    """The dual mortar coupling of a slave and a master boundary part.

    slave_nodes : (ns,) global slave node ids, ordered along the slave part.
    master_nodes : (nm,) global master node ids, ordered along the master part.
    D : (ns,) diagonal entries ∫ψ̃_i φ_i^s (= trace weights ∫φ_i for active nodes, 0 for
        inactive ones).
    M : (ns, nm) csr, M[i, j] = ∫ψ̃_i φ_j^m ∘ π (zero rows for inactive nodes).
    Ds : (n_active, ns) csr, the slave block of the constraint, Ds[k, j] = ∫ψ̃_{a_k} φ_j^s with
        a = flatnonzero(active); diag(D[active]) for ends="keep".
    normals, tangents : (ns, 2) slave nodal unit normals (outward from the slave body) and
        tangents τ = (−n_y, n_x).
    active : (ns,) bool, slave nodes that carry a multiplier.
    coverage : (ns − 1,) or (ns,) fraction of each slave segment covered by projected master
        segments (1 where fully covered; < 1 means part of the slave is left uncoupled).
    """

    slave_nodes: np.ndarray
    master_nodes: np.ndarray
    D: np.ndarray
    M: sp.csr_matrix
    Ds: sp.csr_matrix
    normals: np.ndarray
    tangents: np.ndarray
    active: np.ndarray
    coverage: np.ndarray

    @property
    def M_active(self) -> sp.csr_matrix:
        """(n_active, nm) the master block of the constraint, rows of M for active nodes."""
        return self.M[np.flatnonzero(self.active)]


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _project_nodes(
    xa: np.ndarray, xb: np.ndarray, na: np.ndarray, nb: np.ndarray, y: np.ndarray
) -> np.ndarray:
    """Parameters t with y − x(t) ∥ n(t) on each slave segment: (n_seg, n_points).

    x(t) = xa + t (xb − xa), n(t) = na + t (nb − na); cross(x(t) − y, n(t)) = 0 is a quadratic
    a t² + b t + c; the root nearest to the segment (t = 1/2) is returned, NaN if none is real.
    """
    d0 = xa[:, None, :] - y[None, :, :]  # (n_seg, n_pts, 2)
    d1 = (xb - xa)[:, None, :]  # (n_seg, 1, 2)
    n0, n1 = na[:, None, :], (nb - na)[:, None, :]  # (n_seg, 1, 2)
    a = _cross(d1, n1)  # (n_seg, 1)
    b = _cross(d0, n1) + _cross(d1, n0)  # (n_seg, n_pts)
    c = _cross(d0, n0)  # (n_seg, n_pts)
    disc = b * b - 4 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        q = -0.5 * (b + np.where(b >= 0, 1.0, -1.0) * np.sqrt(disc))  # stable roots q/a, c/q
        r1, r2 = q / a, c / q  # (n_seg, n_pts) each; a = 0 gives r1 = ±inf, r2 = −c/b
    r1, r2 = np.where(np.isfinite(r1), r1, np.inf), np.where(np.isfinite(r2), r2, np.inf)
    t = np.where(abs(r1 - 0.5) < abs(r2 - 0.5), r1, r2)
    return np.where(np.isfinite(t) & (disc >= 0), t, np.nan)


def _merge_ends(ns: int) -> sp.csr_matrix:
    """(ns, ns) R with R[nb, end] = 1 and zero rows for the two ends of an open chain."""
    R = sp.lil_matrix((ns, ns))
    R.setdiag(1.0)
    for end, nb in ((0, 1), (ns - 1, ns - 2)):
        R[end, end] = 0.0
        R[nb, end] = 1.0
    return sp.csr_matrix(R)


def mortar_coupling(
    slave: Mesh,
    slave_part: str,
    master: Mesh,
    master_part: str,
    ends: str = "keep",
    quad_order: int = 5,
) -> Mortar:
    """The dual mortar matrices of `slave_part` (multiplier side) against `master_part`.

    quad_order is the number of Gauss–Legendre points per slave/master piece (exact for a
    straight interface, where the integrand is quadratic; on curved interfaces π is rational in
    t). ends: "keep" or "merge" (see module docstring). The two parts must face each other
    (master segments whose normal does not oppose the slave segment's are ignored); the cost is
    O(n_slave_segments · n_master_nodes).
    """
    if ends not in ("keep", "merge"):
        raise ValueError(f"ends must be 'keep' or 'merge', got {ends!r}")
    ts, tm = trace(slave, slave_part), trace(master, master_part)
    xs, xm = slave.points[ts.nodes], master.points[tm.nodes]  # (ns, 2), (nm, 2)
    ns, nm = ts.size, tm.size
    ea, eb = ts.segments[:, 0], ts.segments[:, 1]  # (n_es,)
    fa, fb = tm.segments[:, 0], tm.segments[:, 1]  # (n_em,)
    xa, xb, na, nb = xs[ea], xs[eb], ts.normals[ea], ts.normals[eb]  # (n_es, 2) each

    T = _project_nodes(xa, xb, na, nb, xm)  # (n_es, nm)
    lo = np.clip(np.minimum(T[:, fa], T[:, fb]), 0.0, 1.0)  # (n_es, n_em)
    hi = np.clip(np.maximum(T[:, fa], T[:, fb]), 0.0, 1.0)
    dm = xm[fb] - xm[fa]  # (n_em, 2)
    facing = (xb - xa) @ dm.T < 0  # opposite traversal ⇔ opposite outward normals
    e, f = np.nonzero(facing & (hi - lo > 1e-14))  # (n_pair,) each
    lo, hi = lo[e, f], hi[e, f]  # (n_pair,)

    g, w = np.polynomial.legendre.leggauss(quad_order)
    g, w = 0.5 * (g + 1.0), 0.5 * w  # (n_qp,) on [0, 1]
    t = lo[:, None] + (hi - lo)[:, None] * g[None, :]  # (n_pair, n_qp)
    psi = dual_basis_on_segment(t)  # (n_pair, n_qp, 2)
    x = xa[e, None] + t[..., None] * (xb - xa)[e, None]  # (n_pair, n_qp, 2)
    n = na[e, None] + t[..., None] * (nb - na)[e, None]  # (n_pair, n_qp, 2)
    eta = _cross(x - xm[fa][f, None], n) / _cross(dm[f, None], n)  # (n_pair, n_qp)
    phi = np.stack([1.0 - eta, eta], axis=-1)  # (n_pair, n_qp, 2)
    jw = (ts.lengths[e] * (hi - lo))[:, None] * w[None, :]  # (n_pair, n_qp)
    loc = np.einsum("pq,pqa,pqb->pab", jw, psi, phi)  # (n_pair, 2, 2)
    rows = ts.segments[e][:, :, None].repeat(2, axis=2)  # (n_pair, 2, 2)
    cols = tm.segments[f][:, None, :].repeat(2, axis=1)  # (n_pair, 2, 2)
    M = sp.csr_matrix((loc.ravel(), (rows.ravel(), cols.ravel())), shape=(ns, nm))
    coverage = np.bincount(e, weights=hi - lo, minlength=ts.segments.shape[0])

    active = np.ones(ns, dtype=bool)
    D = ts.weights.copy()
    Dfull = sp.diags(D).tocsr()  # (ns, ns)
    if ends == "merge":
        if ts.segments.shape[0] != ns - 1 or ns < 3:
            raise ValueError('ends="merge" needs an open slave chain with at least 3 nodes')
        R = _merge_ends(ns)
        M, Dfull = sp.csr_matrix(R @ M), sp.csr_matrix(R @ Dfull)
        active[[0, -1]] = False
        D[[0, -1]] = 0.0
    Ds = sp.csr_matrix(Dfull[np.flatnonzero(active)])
    return Mortar(
        slave_nodes=ts.nodes,
        master_nodes=tm.nodes,
        D=D,
        M=M,
        Ds=Ds,
        normals=ts.normals,
        tangents=ts.tangents,
        active=active,
        coverage=coverage,
    )
