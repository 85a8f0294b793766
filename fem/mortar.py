"""Dual mortar coupling of two non-matching boundary traces in 2D (segment-based).

The multiplier space lives on the SLAVE part, in the segment-local dual functions ψ_{e,a} of
`fem.boundary` (a multiplier basis is Q·ψ, `fem.boundary.multiplier_basis`). The master block is

    M[2e + a, j] = ∫_e ψ_{e,a} (φ_j^m ∘ π) ds,

integrated over each slave segment e, where π maps a slave point x(t) = x_a + t (x_b − x_a) to
the master polyline along the INTERPOLATED slave normal n(t) = (1 − t) n_a + t n_b (Puso, Popp):
π(x(t)) = y_f(η) = y_f0 + η (y_f1 − y_f0) on the master segment f that the line x(t) + α n(t)
meets, i.e. η(t) = cross(x(t) − y_f0, n(t)) / cross(y_f1 − y_f0, n(t)) ∈ [0, 1].

Segments (no global root choice): each slave segment e is paired with the master segments f it
can see — within `reach` of it (a k-d tree search on segment midpoints) and facing it (normals
opposed). For one pair the set {t ∈ [0, 1] : 0 ≤ η(t) ≤ 1} is exact: its boundary points are
roots of the two quadratics cross(x(t) − y, n(t)) = 0 (y a master node: the projection of that
node onto e) and of the linear denominator; on each piece between consecutive roots the sign
pattern is constant, so one midpoint test decides. Where several master segments are hit (a
wide or folded interface: the normal line meets the master polyline more than once), each
elementary interval keeps the NEAREST hit (smallest |x(t) − π(x(t))|), so every slave point is
mapped at most once: the coverage of a segment is ≤ 1 by construction, and = 1 up to rounding
where the master is behind the whole segment. Neighbouring master segments share the root of
their common node bit for bit, so the pieces tile the covered part without gap or overlap.
Each piece gets Gauss–Legendre quadrature (exact on straight interfaces, where the integrand
is quadratic; π is rational in t on curved ones).

Rigid-body patch test: for every multiplier row k, Σ_j D_kj = Σ_j M_kj when the support of ψ̃_k
is covered (Σ_j φ_j^m = 1); `patch_defect` measures max_k |Σ_j D_kj − Σ_j M_kj| / Σ_j D_kj.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .boundary import Trace, dual_basis_on_segment, trace
from .mesh import Mesh


@dataclass(frozen=True, eq=False)
class Mortar:
    """The segment-local dual mortar coupling of a slave and a master boundary part.

    slave : the slave trace (multiplier side); slave.nodes are global slave node ids.
    master_nodes : (nm,) global master node ids, ordered along the master part.
    M : (2·n_seg, nm) csr, M[2e + a, j] = ∫_e ψ_{e,a} (φ_j^m ∘ π) (module docstring).
    coverage : (n_seg,) fraction of each slave segment mapped onto the master (0 … 1).
    """

    slave: Trace
    master_nodes: np.ndarray
    M: sp.csr_matrix
    coverage: np.ndarray

    @property
    def slave_nodes(self) -> np.ndarray:
        """(ns,) global slave node ids, ordered along the slave part."""
        return self.slave.nodes


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _roots_in_unit(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Real roots in (0, 1) of a t² + b t + c, NaN elsewhere: (n, 2).

    Stable form: q = −(b + sign(b)√(b² − 4ac))/2, roots q/a and c/q; a = 0 gives the linear
    root −c/b (q/a is ±inf then and dropped).
    """
    disc = b * b - 4.0 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        q = -0.5 * (b + np.where(b >= 0, 1.0, -1.0) * np.sqrt(np.where(disc >= 0, disc, np.nan)))
        r = np.stack([q / a, c / q], axis=-1)  # (n, 2)
    return np.where(np.isfinite(r) & (r > 0.0) & (r < 1.0), r, np.nan)


def _candidates(
    xs: np.ndarray, ts: Trace, xm: np.ndarray, tm: Trace, reach: float
) -> tuple[np.ndarray, np.ndarray]:
    """Slave/master segment pairs (e, f) within reach of each other and facing each other."""
    ms = 0.5 * (xs[ts.segments[:, 0]] + xs[ts.segments[:, 1]])  # (n_es, 2) midpoints
    mm = 0.5 * (xm[tm.segments[:, 0]] + xm[tm.segments[:, 1]])  # (n_em, 2)
    radius = 0.5 * ts.lengths + 0.5 * tm.lengths.max() + reach * ts.lengths  # (n_es,)
    hits = cKDTree(mm).query_ball_point(ms, radius)  # (n_es,) lists of f
    e = np.repeat(np.arange(len(hits)), [len(h) for h in hits]).astype(int)
    f = np.concatenate([np.asarray(h, dtype=int) for h in hits]) if len(e) else e
    ns = ts.normals[ts.segments[e, 0]] + ts.normals[ts.segments[e, 1]]  # (n_pair, 2)
    dm = xm[tm.segments[f, 1]] - xm[tm.segments[f, 0]]  # (n_pair, 2)
    facing = _cross(dm, ns) > 0  # master outward normal (dm_y, −dm_x) opposes n_s
    return e[facing], f[facing]


def _pair_geometry(xs, ts, xm, tm, e, f):
    """Slave end points/normals and master end points of pairs: six (n, 2) arrays."""
    a, b = ts.segments[e, 0], ts.segments[e, 1]
    return xs[a], xs[b], ts.normals[a], ts.normals[b], xm[tm.segments[f, 0]], xm[tm.segments[f, 1]]


def _hit(t, xa, xb, na, nb, ya, yb) -> tuple[np.ndarray, np.ndarray]:
    """η(t) on the master segment and the distance |x(t) − y(η)| along the normal line."""
    x = xa + t[:, None] * (xb - xa)  # (n, 2)
    n = na + t[:, None] * (nb - na)  # (n, 2)
    dm = yb - ya
    with np.errstate(divide="ignore", invalid="ignore"):
        eta = _cross(x - ya, n) / _cross(dm, n)  # (n,)
    dist = np.linalg.norm(ya + eta[:, None] * dm - x, axis=1)
    return eta, dist


def _overlaps(xa, xb, na, nb, ya, yb) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pieces [lo, hi] ⊂ [0, 1] of each pair where 0 ≤ η(t) ≤ 1: (pair index, lo, hi)."""
    d1, n1 = xb - xa, nb - na  # (n, 2)
    roots = [np.zeros((len(xa), 1)), np.ones((len(xa), 1))]
    for y in (ya, yb):  # cross(x(t) − y, n(t)) = 0: master node y projects to x(t)
        d0 = xa - y
        roots.append(
            _roots_in_unit(_cross(d1, n1), _cross(d0, n1) + _cross(d1, na), _cross(d0, na))
        )
    dm = yb - ya
    roots.append(_roots_in_unit(np.zeros(len(xa)), _cross(dm, n1), _cross(dm, na))[:, :1])
    T = np.sort(np.concatenate(roots, axis=1), axis=1)  # (n, 7), NaN last
    T = np.where(np.isnan(T), 1.0, T)
    lo, hi = T[:, :-1], T[:, 1:]  # (n, 6) sub-intervals
    p = np.repeat(np.arange(len(xa)), lo.shape[1])
    lo, hi = lo.ravel(), hi.ravel()
    keep = hi > lo
    p, lo, hi = p[keep], lo[keep], hi[keep]
    eta, _ = _hit(0.5 * (lo + hi), xa[p], xb[p], na[p], nb[p], ya[p], yb[p])
    inside = (eta >= 0.0) & (eta <= 1.0)
    return p[inside], lo[inside], hi[inside]


def _nearest(e, f, lo, hi, geometry) -> tuple[np.ndarray, ...]:
    """Split the pieces of each slave segment at every piece end; keep, on each elementary
    interval, the piece whose master point is nearest. Returns (e, f, lo, hi) of the result."""
    if e.size == 0:
        return e, f, lo, hi
    # elementary intervals: consecutive distinct break points per slave segment
    be, bt = np.concatenate([e, e]), np.concatenate([lo, hi])
    order = np.lexsort((bt, be))
    be, bt = be[order], bt[order]
    nxt = np.flatnonzero((be[1:] == be[:-1]) & (bt[1:] > bt[:-1]))
    ee, elo, ehi = be[nxt], bt[nxt], bt[nxt + 1]  # (n_el,)
    # join each elementary interval with the pieces of its slave segment (ragged expansion)
    porder = np.argsort(e, kind="stable")
    start = np.searchsorted(e[porder], ee, side="left")
    count = np.searchsorted(e[porder], ee, side="right") - start
    j = np.repeat(np.arange(ee.size), count)  # (n_join,) elementary interval
    k = porder[np.repeat(start - count.cumsum() + count, count) + np.arange(count.sum())]
    mid = 0.5 * (elo[j] + ehi[j])
    inside = (lo[k] <= mid) & (mid <= hi[k])
    j, k, mid = j[inside], k[inside], mid[inside]
    _, dist = _hit(mid, *(g[k] for g in geometry))
    best = np.lexsort((dist, j))  # by interval, nearest first
    first = best[np.r_[True, j[best][1:] != j[best][:-1]]]
    j, k = j[first], k[first]
    return ee[j], f[k], elo[j], ehi[j]


def mortar_coupling(
    slave: Mesh,
    slave_part: str,
    master: Mesh,
    master_part: str,
    quad_order: int = 5,
    reach: float = 1.0,
) -> Mortar:
    """The segment-local dual mortar matrices of `slave_part` against `master_part`.

    quad_order : Gauss–Legendre points per piece (exact for a straight interface).
    reach : a master segment is seen by a slave segment e if their midpoints are at most
        |e|/2 + (longest master segment)/2 + reach·|e| apart (and they face each other);
        the default admits interfaces that coincide up to about one slave segment length.
    Cost: O(n_pairs) with n_pairs ≈ (segments) × (master segments per slave segment).
    """
    ts, tm = trace(slave, slave_part), trace(master, master_part)
    xs, xm = slave.points[ts.nodes], master.points[tm.nodes]  # (ns, 2), (nm, 2)
    nm, n_es = tm.size, ts.segments.shape[0]
    e, f = _candidates(xs, ts, xm, tm, reach)  # (n_pair,) each
    p, lo, hi = _overlaps(*_pair_geometry(xs, ts, xm, tm, e, f))
    e, f = e[p], f[p]
    e, f, lo, hi = _nearest(e, f, lo, hi, _pair_geometry(xs, ts, xm, tm, e, f))
    geo = _pair_geometry(xs, ts, xm, tm, e, f)  # six (n_piece, 2)

    g, w = np.polynomial.legendre.leggauss(quad_order)
    g, w = 0.5 * (g + 1.0), 0.5 * w  # (n_qp,) on [0, 1]
    t = lo[:, None] + (hi - lo)[:, None] * g[None, :]  # (n_piece, n_qp)
    eta, _ = _hit(t.ravel(), *(np.repeat(v, quad_order, axis=0) for v in geo))
    eta = eta.reshape(t.shape)  # (n_piece, n_qp)
    psi = dual_basis_on_segment(t)  # (n_piece, n_qp, 2)
    phi = np.stack([1.0 - eta, eta], axis=-1)  # (n_piece, n_qp, 2)
    jw = (ts.lengths[e] * (hi - lo))[:, None] * w[None, :]  # (n_piece, n_qp)
    loc = np.einsum("pq,pqa,pqb->pab", jw, psi, phi)  # (n_piece, 2, 2)
    rows = (2 * e[:, None] + np.arange(2)[None, :])[:, :, None].repeat(2, axis=2)  # (n_piece, 2, 2)
    cols = tm.segments[f][:, None, :].repeat(2, axis=1)  # (n_piece, 2, 2)
    M = sp.csr_matrix((loc.ravel(), (rows.ravel(), cols.ravel())), shape=(2 * n_es, nm))
    coverage = np.bincount(e, weights=hi - lo, minlength=n_es)
    return Mortar(slave=ts, master_nodes=tm.nodes, M=M, coverage=coverage)


def patch_defect(Ds: sp.spmatrix, M: sp.spmatrix) -> np.ndarray:
    """Per multiplier row k: |Σ_j Ds_kj − Σ_j M_kj| / Σ_j Ds_kj (0 ⇔ rigid translations are
    transferred exactly by row k)."""
    d = np.asarray(Ds.sum(axis=1)).ravel()
    m = np.asarray(M.sum(axis=1)).ravel()
    return np.abs(d - m) / d
