"""The dimension-specific half of the dual mortar `fem.mortar`: where a slave facet meets the
master, as integration points in both facets' reference coordinates.

Both halves map a slave point x to the master along the INTERPOLATED slave normal
n = Σ_a φ_a n_a (Puso, Popp), keep for every slave point the NEAREST master hit where the normal
line meets the master more than once, and return `Pieces`: per integration piece the slave and
master facet, the reference points of its quadrature points on both, and weights on the slave
facet (so that the weights of a fully covered slave facet add up to its measure).

2D, segment overlaps (`segment_pieces`). A slave point x(t) = x_a + t (x_b − x_a) of segment e
with normal n(t) = (1 − t) n_a + t n_b is mapped to y_f(η) = y_f0 + η (y_f1 − y_f0) on the
master segment f that the line x(t) + α n(t) meets, η(t) = cross(x(t) − y_f0, n(t)) /
cross(y_f1 − y_f0, n(t)) ∈ [0, 1]. Each slave segment e is paired with the master segments f it
can see — within `reach` of it (a k-d tree search on segment midpoints) and facing it (normals
opposed). For one pair the set {t ∈ [0, 1] : 0 ≤ η(t) ≤ 1} is exact: its boundary points are
roots of the two quadratics cross(x(t) − y, n(t)) = 0 (y a master node: the projection of that
node onto e) and of the linear denominator; on each piece between consecutive roots the sign
pattern is constant, so one midpoint test decides. Where several master segments are hit (a
wide or folded interface), each elementary interval keeps the nearest hit (smallest
|x(t) − π(x(t))|), so the coverage of a segment is ≤ 1 by construction, and = 1 up to rounding
where the master is behind the whole segment. Neighbouring master segments share the root of
their common node bit for bit, so the pieces tile the covered part without gap or overlap.
Each piece gets Gauss–Legendre quadrature (exact on straight interfaces, where the integrand
is quadratic; π is rational in t on curved ones).

3D, polygon clipping (`polygon_pieces`) in an auxiliary plane per slave face (Puso–Laursen
2004, Popp et al. 2010):

1. the plane of slave face e passes through its centre x0 (ξ = 0 of a quadrilateral, the
   centroid of a triangle) with normal n0 = the nodal normals interpolated there;
2. the slave face is projected orthogonally onto the plane; each node y of a master face near
   it and facing it (outward normals opposed) is carried to the slave point whose normal line
   passes through y (Newton on x(ξ) + α n(ξ) = y) and that point is projected onto the plane;
   the master polygon is clipped against the (convex) slave polygon (Sutherland–Hodgman);
3. each clip polygon is split into triangles about its vertex mean; on each triangle the
   triangle rule of `fem.elements` (collapsed Gauss at the default orders of `fem.mortar`);
   every quadrature point y goes back to the slave parameters by
   inverting the orthogonal projection (affine for a triangle, Newton for a bilinear
   quadrilateral), and from the slave point x(ξ_s) along n(ξ_s) to the master face's
   parameters (Newton on x_m(η) − β n = x);
4. the weight of y is its plane weight times |N_s|/|N_s·n0| (N_s = ∂x/∂ξ × ∂x/∂η of the slave
   face at ξ_s(y)): the integral is over the SLAVE surface.

The textbook auxiliary-plane method projects along the constant n0 instead; that is
discontinuous from face to face and does not reduce to the 2D coupling on an extruded mesh
(5e-4 relative on the paper's level-0 meshes). With the normal field, a 2D mesh extruded in z
(faces = segment × [z0, z1], normals ⟂ z) gets in each section exactly the pieces and the
projection of the 2D half, and M = thickness × the 2D M to rounding.

Folded masters (`nearest_hits`): where the normal lines of a slave face meet two master faces,
the nearer one wins, as in 2D: the overlap of the two cells is integrated again for the
farther face with weight −1 (exact for two sheets; a master folded twice under one slave face
is refused). Limits: a projected slave face must be convex (true for any non-degenerate
triangle and for quadrilaterals that are not badly warped); master faces are cut along the
straight chords between their nodes' images (the cells still tile the slave face exactly,
only the split between neighbouring master faces moves, by O(h³)); a slave that has
penetrated a thin master deeper than half its thickness is coupled to the far sheet.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from .elements import reference_element
from .facets import Trace, facet_values
from .jacobians import solve2


class Pieces(NamedTuple):
    """Integration points of the slave/master overlap (n pieces, q points each).

    e, f : (n,) slave and master facet of each piece.
    xi_s, xi_m : (n, q, d − 1) reference points on the slave and on the master facet.
    weights : (n, q) quadrature weights on the slave facet (negative on a taken-back overlap).
    n_cells : number of overlap cells (2D pieces, 3D non-empty clip polygons) before the
        nearest-hit rule.
    """

    e: np.ndarray
    f: np.ndarray
    xi_s: np.ndarray
    xi_m: np.ndarray
    weights: np.ndarray
    n_cells: int


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


def _segment_candidates(
    xs: np.ndarray, ts: Trace, xm: np.ndarray, tm: Trace, reach: float
) -> tuple[np.ndarray, np.ndarray]:
    """Slave/master segment pairs (e, f) within reach of each other and facing each other."""
    ms = 0.5 * (xs[ts.facets[:, 0]] + xs[ts.facets[:, 1]])  # (n_es, 2) midpoints
    mm = 0.5 * (xm[tm.facets[:, 0]] + xm[tm.facets[:, 1]])  # (n_em, 2)
    radius = 0.5 * ts.measures + 0.5 * tm.measures.max() + reach * ts.measures  # (n_es,)
    hits = cKDTree(mm).query_ball_point(ms, radius)  # (n_es,) lists of f
    e = np.repeat(np.arange(len(hits)), [len(h) for h in hits]).astype(int)
    f = np.concatenate([np.asarray(h, dtype=int) for h in hits]) if len(e) else e
    ns = ts.normals[ts.facets[e, 0]] + ts.normals[ts.facets[e, 1]]  # (n_pair, 2)
    dm = xm[tm.facets[f, 1]] - xm[tm.facets[f, 0]]  # (n_pair, 2)
    facing = _cross(dm, ns) > 0  # master outward normal (dm_y, −dm_x) opposes n_s
    return e[facing], f[facing]


def _pair_geometry(xs, ts, xm, tm, e, f):
    """Slave end points/normals and master end points of pairs: six (n, 2) arrays."""
    a, b = ts.facets[e, 0], ts.facets[e, 1]
    return xs[a], xs[b], ts.normals[a], ts.normals[b], xm[tm.facets[f, 0]], xm[tm.facets[f, 1]]


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


def segment_pieces(ts: Trace, tm: Trace, reach: float, order: int) -> Pieces:
    """The 2D half: overlaps of slave segments with the master segments they see along the
    interpolated normal (module docstring), Gauss–Legendre of degree `order` on each piece.

    reach : a master segment is seen by a slave segment e if their midpoints are at most
        |e|/2 + (longest master segment)/2 + reach·|e| apart (and they face each other).
    """
    xs, xm = ts.points, tm.points  # (ns, 2), (nm, 2)
    e, f = _segment_candidates(xs, ts, xm, tm, reach)  # (n_pair,) each
    p, lo, hi = _overlaps(*_pair_geometry(xs, ts, xm, tm, e, f))
    e, f = e[p], f[p]
    n_cells = int(e.size)
    e, f, lo, hi = _nearest(e, f, lo, hi, _pair_geometry(xs, ts, xm, tm, e, f))
    geo = _pair_geometry(xs, ts, xm, tm, e, f)  # six (n_piece, 2)
    g, w = reference_element("line").quadrature(order)  # (n_qp, 1), (n_qp,) on [0, 1]
    t = lo[:, None] + (hi - lo)[:, None] * g[None, :, 0]  # (n_piece, n_qp)
    eta, _ = _hit(t.ravel(), *(np.repeat(v, w.size, axis=0) for v in geo))
    jw = (ts.measures[e] * (hi - lo))[:, None] * w[None, :]  # (n_piece, n_qp)
    return Pieces(e, f, t[..., None], eta.reshape(t.shape)[..., None], jw, n_cells)


# --- 3D: polygon clipping -------------------------------------------------------------


def _planes(s: Trace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Auxiliary planes of the slave faces: centres x0 (n_f, 3), unit normals n0 (n_f, 3) and
    in-plane axes E (n_f, 3, 2) with e1 × e2 = n0."""
    x0 = s.points[s.facets].mean(axis=1)  # (n_f, 3): ξ = 0 of a Q1 face, centroid of a P1 face
    n0 = s.normals[s.facets].mean(axis=1)  # (n_f, 3) φ_a(centre) = 1/m
    n0 /= np.linalg.norm(n0, axis=1)[:, None]
    axis = np.eye(3)[np.argmin(np.abs(n0), axis=1)]  # (n_f, 3) least aligned axis
    e1 = axis - np.einsum("fi,fi->f", axis, n0)[:, None] * n0
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    return x0, n0, np.stack([e1, np.cross(n0, e1)], axis=2)


def _face_normal(f: Trace) -> np.ndarray:
    """(n_f, 3) ∂x/∂ξ × ∂x/∂η at the face centre (outward, not normalised)."""
    X = f.points[f.facets]  # (n_f, m, 3)
    if f.facet_type == "triangle":
        return np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    return np.cross(X[:, 1] + X[:, 2] - X[:, 0] - X[:, 3], X[:, 2] + X[:, 3] - X[:, 0] - X[:, 1])


def _face_candidates(s: Trace, m: Trace, x0, n0, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Slave/master face pairs (e, f) near each other and facing each other."""
    cs, cm = x0, m.points[m.facets].mean(axis=1)  # (n_fs, 3), (n_fm, 3)
    rs = np.linalg.norm(s.points[s.facets] - cs[:, None], axis=2).max(axis=1)  # (n_fs,)
    rm = np.linalg.norm(m.points[m.facets] - cm[:, None], axis=2).max()
    hits = cKDTree(cm).query_ball_point(cs, rs * (1.0 + reach) + rm)
    e = np.repeat(np.arange(len(hits)), [len(h) for h in hits]).astype(int)
    f = np.concatenate([np.asarray(h, dtype=int) for h in hits]) if e.size else e
    facing = np.einsum("pi,pi->p", _face_normal(m)[f], n0[e]) < 0
    return e[facing], f[facing]


def clip(subject: np.ndarray, count: np.ndarray, window: np.ndarray, tol: float = 1e-15):
    """Sutherland–Hodgman, vectorised over polygons: each subject polygon (n, K, 2) with
    count (n,) vertices clipped against a convex counterclockwise window (n, w, 2).

    Returns the clipped polygons (n, K', 2) (vertices past their count are padding) and their
    vertex counts (n,) (< 3: empty); vertices within tol × (window size) of the next one are
    merged.
    """
    P, c = subject, count
    n, w = window.shape[:2]
    if n == 0:
        return P, c
    for j in range(w):
        A, B = window[:, j], window[:, (j + 1) % w]  # (n, 2) the clip edge, inside on the left
        i = np.arange(P.shape[1])[None, :]  # (1, K)
        valid = i < c[:, None]  # (n, K)
        Q = np.take_along_axis(P, np.where(i + 1 < c[:, None], i + 1, 0)[..., None], axis=1)
        d_p = _cross((B - A)[:, None], P - A[:, None])  # (n, K) ≥ 0: inside
        d_q = _cross((B - A)[:, None], Q - A[:, None])
        keep = valid & (d_p >= 0)
        cut = valid & ((d_p >= 0) != (d_q >= 0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(cut, d_p / (d_p - d_q), 0.0)  # (n, K)
        X = P + t[..., None] * (Q - P)  # (n, K, 2) the crossing of edge P→Q
        slots = np.stack([P, X], axis=2).reshape(n, -1, 2)  # (n, 2K, 2): P_i, then its cut
        ok = np.stack([keep, cut], axis=2).reshape(n, -1)  # (n, 2K)
        order = np.argsort(~ok, axis=1, kind="stable")
        c = ok.sum(axis=1)
        P = np.take_along_axis(slots, order[..., None], axis=1)[:, : max(int(c.max(initial=0)), 1)]
    return _distinct(P, c, tol * np.abs(window).max())


def _distinct(P: np.ndarray, c: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Polygons (n, K, 2) with counts (n,) without vertices closer than tol to the next one
    (the duplicates that clipping makes where edges or vertices coincide), so that the vertex
    mean, and with it the cell triangles, do not depend on rounding."""
    i = np.arange(P.shape[1])[None, :]  # (1, K)
    nxt = np.take_along_axis(P, np.where(i + 1 < c[:, None], i + 1, 0)[..., None], axis=1)
    ok = (i < c[:, None]) & (np.abs(nxt - P).max(axis=2) > tol)  # (n, K)
    order = np.argsort(~ok, axis=1, kind="stable")
    return np.take_along_axis(P, order[..., None], axis=1), ok.sum(axis=1)


def _coefficients(face_type: str, X: np.ndarray) -> tuple[np.ndarray, ...]:
    """x(ξ, η) = p + b ξ + c η + d ξη of faces X (n, m, k): (p, b, c, d), each (n, 1, k)
    (d = 0 for a triangle, whose reference is (0,0)-(1,0)-(0,1); a quadrilateral's is [−1, 1]²)."""
    if face_type == "triangle":
        p, b, c = X[:, 0], X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]
        d = np.zeros_like(p)
    else:
        p = 0.25 * X.sum(axis=1)
        b = 0.25 * (-X[:, 0] + X[:, 1] + X[:, 2] - X[:, 3])
        c = 0.25 * (-X[:, 0] - X[:, 1] + X[:, 2] + X[:, 3])
        d = 0.25 * (X[:, 0] - X[:, 1] + X[:, 2] - X[:, 3])
    return p[:, None], b[:, None], c[:, None], d[:, None]


def _evaluate(coef: tuple[np.ndarray, ...], xi: np.ndarray) -> tuple[np.ndarray, ...]:
    """x (n, q, k), ∂x/∂ξ and ∂x/∂η (n, q, k) at reference points xi (n, q, 2)."""
    p, b, c, d = coef
    s, t = xi[..., :1], xi[..., 1:]  # (n, q, 1)
    return p + b * s + c * t + d * s * t, b + d * t, c + d * s


def inverse_map(face_type: str, P: np.ndarray, y: np.ndarray, tol: float = 1e-11) -> np.ndarray:
    """Reference points ξ (n, q, 2) with Σ_a φ_a(ξ) P_a = y, for plane faces P (n, m, 2) and
    points y (n, q, 2): affine for a triangle, Newton from ξ = 0 for a quadrilateral.

    ValueError if Newton does not reach |Δξ| ≤ tol in 30 steps (a degenerate projected face).
    """
    coef = _coefficients(face_type, P)
    xi = np.zeros(y.shape)  # (n, q, 2)
    for _ in range(30):
        x, xs, xt = _evaluate(coef, xi)  # (n, q, 2) each
        step = solve2(np.stack([xs, xt], axis=-1), x - y)
        xi -= step
        if face_type == "triangle" or np.abs(step).max(initial=0.0) <= tol:
            return xi
    raise ValueError("inverse bilinear map did not converge (degenerate projected face)")


def _tangent_cross(face_type: str, X: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """N = ∂x/∂ξ × ∂x/∂η (n, q, 3) of faces X (n, m, 3) at reference points xi (n, q, 2)."""
    _, xs, xt = _evaluate(_coefficients(face_type, X), xi)
    return np.cross(xs, xt)


def _solve3(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """J⁻¹ r for stacks of 3×3 matrices J (..., 3, 3) and vectors r (..., 3) (Cramer)."""
    a, b, c = J[..., 0], J[..., 1], J[..., 2]  # (..., 3) columns
    bc = np.cross(b, c)
    det = np.einsum("...i,...i->...", a, bc)
    x = np.stack(
        [
            np.einsum("...i,...i->...", r, bc),
            np.einsum("...i,...i->...", a, np.cross(r, c)),
            np.einsum("...i,...i->...", a, np.cross(b, r)),
        ],
        axis=-1,
    )
    return x / det[..., None]


def _rays(
    face_type: str,
    X: np.ndarray,
    y: np.ndarray,
    xi: np.ndarray,
    dirs: np.ndarray | None = None,
    normals: np.ndarray | None = None,
    tol: float = 1e-11,
) -> np.ndarray:
    """Newton for the points of faces X (n, m, 3) on rays: reference points ξ (n, q, 2) with

    x(ξ) + α n(ξ) = y (n, q, 3), n(ξ) = Σ_a φ_a(ξ) normals_a (normals (n, m, 3): the slave's
    interpolated nodal normals; the face point whose normal line passes through y), or
    x(ξ) − α d = y for fixed directions d = dirs (n, q, 3) (where the ray y + α d meets the face).
    Starts from xi (n, q, 2) and α = 0; ValueError if |Δξ| ≤ tol is not reached in 30 steps.
    """
    cx = _coefficients(face_type, X)
    cn = None if normals is None else _coefficients(face_type, normals)
    alpha = np.zeros(y.shape[:-1] + (1,))  # (n, q, 1)
    for _ in range(30):
        x, xs, xt = _evaluate(cx, xi)  # (n, q, 3) each
        if cn is None:
            d = -dirs
        else:
            d, ns, nt = _evaluate(cn, xi)
            xs, xt = xs + alpha * ns, xt + alpha * nt
        step = _solve3(np.stack([xs, xt, d], axis=-1), x + alpha * d - y)  # (n, q, 3)
        xi = xi - step[..., :2]
        alpha = alpha - step[..., 2:]
        if np.abs(step[..., :2]).max(initial=0.0) <= tol:
            return xi
    raise ValueError("projection along the normals did not converge (degenerate faces)")


def cells(s: Trace, m: Trace, reach: float = 1.0):
    """The integration cells: clip polygons of every facing slave/master face pair.

    The slave face is projected orthogonally onto its auxiliary plane; each master node y is
    carried to the slave point x_s(ξ) whose interpolated normal line passes through it, and
    that point is projected onto the plane (so the cells follow the projection along the
    normal field, as the 2D pieces of `segment_pieces` do).

    Returns (e, f, poly, count, x0, n0, E): slave face (n_c,), master face (n_c,), polygons
    (n_c, K, 2) in plane coordinates of the slave face's auxiliary plane (counterclockwise about
    n0), their vertex counts (n_c,) ≥ 3, and the planes of all slave faces (`_planes`).
    """
    x0, n0, E = _planes(s)
    e, f = _face_candidates(s, m, x0, n0, reach)
    Xs = s.points[s.facets[e]]  # (n_p, m_s, 3)
    S = np.einsum("pai,pij->paj", Xs - x0[e][:, None], E[e])  # (n_p, m_s, 2)
    Y = m.points[m.facets[f]]  # (n_p, m_m, 3)
    xi = inverse_map(s.facet_type, S, np.einsum("pai,pij->paj", Y - x0[e][:, None], E[e]))
    xi = _rays(s.facet_type, Xs, Y, xi, normals=s.normals[s.facets[e]])  # (n_p, m_m, 2)
    phi = facet_values(s.facet_type, xi)  # (n_p, m_m, m_s)
    foot = np.einsum("pba,pai->pbi", phi, Xs)  # (n_p, m_m, 3) slave points below master nodes
    Mp = np.einsum("pai,pij->paj", foot - x0[e][:, None], E[e])  # (n_p, m_m, 2)
    Mp = Mp[:, ::-1]  # the master face is counterclockwise about −n0: reverse it
    poly, count = clip(Mp, np.full(e.size, Mp.shape[1]), S)
    keep = count >= 3
    return e[keep], f[keep], poly[keep], count[keep], x0, n0, E


def _area(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """(n,) signed areas of polygons (n, K, 2) with counts (n,) (shoelace)."""
    i = np.arange(poly.shape[1])[None, :]  # (1, K)
    nxt = np.take_along_axis(poly, np.where(i + 1 < count[:, None], i + 1, 0)[..., None], 1)
    return 0.5 * np.where(i < count[:, None], _cross(poly, nxt), 0.0).sum(axis=1)


def _below(s: Trace, m: Trace, e, f, y, x0, E) -> tuple[np.ndarray, ...]:
    """Plane points y (n, q, 2) of slave faces e (n,) carried to the slave and along its normal
    field to master faces f (n,): slave reference points xs (n, q, 2), slave points x and
    normals (n, q, 3) there, reference points xm (n, q, 2) where those lines meet f."""
    Xs, Xm = s.points[s.facets[e]], m.points[m.facets[f]]  # (n, m_s, 3), (n, m_m, 3)
    Ps = np.einsum("nai,nij->naj", Xs - x0[e][:, None], E[e])  # (n, m_s, 2)
    Pm = np.einsum("nai,nij->naj", Xm - x0[e][:, None], E[e])  # (n, m_m, 2)
    xs = inverse_map(s.facet_type, Ps, y)  # (n, q, 2)
    phi = facet_values(s.facet_type, xs)  # (n, q, m_s)
    x = np.einsum("nqa,nai->nqi", phi, Xs)  # (n, q, 3)
    nrm = np.einsum("nqa,nai->nqi", phi, s.normals[s.facets[e]])  # (n, q, 3)
    return xs, x, nrm, _rays(m.facet_type, Xm, x, inverse_map(m.facet_type, Pm, y), dirs=nrm)


def _hit_distance(s: Trace, m: Trace, e, f, y, x0, E) -> np.ndarray:
    """(n,) |x − π_f(x)| of the slave points x of faces e below plane points y (n, 2): how far
    along the interpolated normal the line meets master face f."""
    _, x, _, xm = _below(s, m, e, f, y[:, None], x0, E)  # x (n, 1, 3), xm (n, 1, 2)
    hit = np.einsum("nqb,nbi->nqi", facet_values(m.facet_type, xm), m.points[m.facets[f]])
    return np.linalg.norm(hit - x, axis=2)[:, 0]


def _overlapping(key: np.ndarray, poly: np.ndarray, count: np.ndarray, area: np.ndarray, tol):
    """Pairs (a, b) of polygons (n, K, 2) with counts (n,) and the same key (n,) whose
    intersection has more than tol × area[a] (convex polygons; Sutherland–Hodgman): (a, b,
    intersections (n_o, K', 2), their counts)."""
    order = np.argsort(key, kind="stable")
    pa, pb = [np.zeros(0, dtype=int)], [np.zeros(0, dtype=int)]
    for d in range(1, int(np.bincount(key).max(initial=1)) if key.size else 1):
        same = key[order[:-d]] == key[order[d:]]
        pa.append(order[:-d][same])
        pb.append(order[d:][same])
    a, b = np.concatenate(pa), np.concatenate(pb)
    out = [(a[:0], b[:0], np.zeros((0, 3, 2)), np.zeros(0, dtype=int))]
    for w in np.unique(count[b]):  # clip needs windows of one vertex count
        sel = np.flatnonzero(count[b] == w)
        P, c = clip(poly[a[sel]], count[a[sel]], poly[b[sel], :w])
        ok = (c >= 3) & (np.abs(_area(P, c)) > tol * area[a[sel]])
        out.append((a[sel][ok], b[sel][ok], P[ok], c[ok]))
    width = max(o[2].shape[1] for o in out)
    pad = [np.pad(o[2], ((0, 0), (0, width - o[2].shape[1]), (0, 0))) for o in out]
    return (*(np.concatenate([o[i] for o in out]) for i in (0, 1)), np.concatenate(pad),
            np.concatenate([o[3] for o in out]))  # fmt: skip


def nearest_hits(s: Trace, m: Trace, e, f, poly, count, x0, E, tol: float = 1e-12):
    """Overlap cells for a master that folds back under a slave face: where the cells of two
    master faces overlap on one slave face (the normal line meets both), the nearer face wins
    (as `segment_pieces` in 2D): the overlap polygon (the convex intersection of the two cells) is
    appended as a cell of the FARTHER face with weight −1, so that its integral is taken back.
    Nearer and farther are decided at the overlap's vertex mean (two sheets of one surface do
    not cross). Exact for two sheets; three cells over one point (a second fold) would be taken
    back twice: ValueError. Overlaps below tol × the slave face's area (cells of neighbouring
    master faces touching along an edge) are ignored.

    Returns (sign (n',), e, f, poly, count): the input cells with sign 1, then the overlaps.
    """
    sign = np.ones(e.size)
    oa, ob, op, oc = _overlapping(e, poly, count, s.measures[e], tol)
    if oa.size == 0:
        return sign, e, f, poly, count
    i = np.arange(op.shape[1])[None, :]
    ctr = (op * (i < oc[:, None])[..., None]).sum(axis=1) / oc[:, None]  # (n_o, 2)
    da = _hit_distance(s, m, e[oa], f[oa], ctr, x0, E)
    db = _hit_distance(s, m, e[ob], f[ob], ctr, x0, E)
    far = np.where(da <= db, ob, oa)  # (n_o,) the cell whose face is farther
    if _overlapping(far, op, oc, s.measures[e[far]], tol)[0].size:
        raise ValueError("a master surface folds more than once under a slave face")
    width = max(poly.shape[1], op.shape[1])
    poly = np.pad(poly, ((0, 0), (0, width - poly.shape[1]), (0, 0)))
    op = np.pad(op, ((0, 0), (0, width - op.shape[1]), (0, 0)))
    return (
        np.concatenate([sign, -np.ones(oa.size)]),
        np.concatenate([e, e[far]]),
        np.concatenate([f, f[far]]),
        np.concatenate([poly, op]),
        np.concatenate([count, oc]),
    )


def polygon_pieces(s: Trace, m: Trace, reach: float, order: int) -> Pieces:
    """The 3D half: clip polygons of slave and master faces in the slave faces' auxiliary
    planes (module docstring), split into triangles about their vertex means, the triangle rule
    of total degree `order` (`fem.elements`) on each.

    reach : a master face is a candidate for a slave face e if their centres are at most
        (1 + reach)·r_e + r_max apart (r: the largest centre-to-node distance of a face).
    """
    e, f, poly, count, x0, n0, E = cells(s, m, reach)
    n_cells = int(e.size)
    sign, e, f, poly, count = nearest_hits(s, m, e, f, poly, count, x0, E)
    K = poly.shape[1]
    i = np.arange(K)[None, :]  # (1, K)
    valid = i < count[:, None]  # (n_c, K)
    ctr = (poly * valid[..., None]).sum(axis=1) / count[:, None]  # (n_c, 2)
    nxt = np.take_along_axis(poly, np.where(i + 1 < count[:, None], i + 1, 0)[..., None], 1)
    c, k = np.nonzero(valid)  # (n_t,) cell and vertex of every cell triangle
    a, b = poly[c, k] - ctr[c], nxt[c, k] - ctr[c]  # (n_t, 2) edge vectors from the centre
    area2 = _cross(a, b) * sign[c]  # (n_t,) twice the signed area (−: a taken-back overlap)
    pts, wq = reference_element("triangle").quadrature(order)  # (q, 2), (q,)
    y = ctr[c][:, None] + pts[None, :, :1] * a[:, None] + pts[None, :, 1:] * b[:, None]
    et, ft = e[c], f[c]  # (n_t,) slave and master face of each triangle
    xs, _, n, xm = _below(s, m, et, ft, y, x0, E)  # (n_t, q, 2), _, (n_t, q, 3), (n_t, q, 2)
    Ns = _tangent_cross(s.facet_type, s.points[s.facets[et]], xs)  # (n_t, q, 3)
    ratio = np.linalg.norm(Ns, axis=2) / np.abs(np.einsum("tqi,ti->tq", Ns, n0[et]))
    wt = area2[:, None] * wq[None, :] * ratio  # (n_t, q) slave-surface weights
    return Pieces(et, ft, xs, xm, wt, n_cells)
