"""Dual mortar coupling of two non-matching boundary surfaces in 3D (segment-based).

The 3D analogue of `fem.mortar`. The multiplier space lives on the SLAVE surface, in the
face-local dual functions ψ_{e,a} (a multiplier basis is Q·ψ, `multiplier_basis`):

    ψ_{e,a} = Σ_b A_e[a, b] φ_{e,b},   A_e = D_e M_e⁻¹,   M_e[a, b] = ∫_e φ_a φ_b dA,
    D_e = diag(Σ_b M_e[a, b]),

so that ∫_e ψ_{e,a} φ_{e,b} dA = δ_ab ∫_e φ_a dA and the slave block D = diag(∫_Γ φ_k dA) is
diagonal (P1 triangles: ψ_a = 3φ_a − Σ_{b≠a} φ_b; Q1 parallelograms: the tensor product of the
1D (2, −1) rule; other bilinear quadrilaterals: A_e from their own Jacobian). The master block
is

    M[k e + a, j] = ∫_e ψ_{e,a} (φ_j^m ∘ π) dA,

integrated over each slave face e (k nodes per face), where π maps a slave point x(ξ) to the
master surface along its interpolated normal n(ξ) = Σ_a φ_a(ξ) n_a (as `fem.mortar` does in 2D;
nodal normals n_k ∝ ∫_Γ φ_k n dA: averaged, continuous on curved surfaces). Segments are built
in an auxiliary plane per slave face (Puso–Laursen 2004, Popp et al. 2010):

1. the plane of slave face e passes through its centre x0 (ξ = 0 of a quadrilateral, the
   centroid of a triangle) with normal n0 = the nodal normals interpolated there;
2. the slave face is projected orthogonally onto the plane; each node y of a master face near
   it and facing it (outward normals opposed) is carried to the slave point whose normal line
   passes through y (Newton on x(ξ) + α n(ξ) = y) and that point is projected onto the plane;
   the master polygon is clipped against the (convex) slave polygon (Sutherland–Hodgman);
3. each clip polygon is split into triangles about its vertex mean; on each triangle a
   collapsed Gauss rule; every quadrature point y goes back to the slave parameters by
   inverting the orthogonal projection (affine for a triangle, Newton for a bilinear
   quadrilateral), and from the slave point x(ξ_s) along n(ξ_s) to the master face's
   parameters (Newton on x_m(η) − β n = x);
4. the integral is over the SLAVE surface: the weight of y is its plane weight times
   |N_s|/|N_s·n0| (N_s = ∂x/∂ξ × ∂x/∂η of the slave face at ξ_s(y)), so that the cells of a
   fully covered slave face add up to ∫_e ψ_{e,a} dA = ∫_e φ_a dA, the entry of D.

The textbook auxiliary-plane method projects along the constant n0 instead; that is
discontinuous from face to face and does not reduce to the 2D coupling on an extruded mesh
(5e-4 relative on the paper's level-0 meshes). With the normal field, a 2D mesh extruded in z
(faces = segment × [z0, z1], normals ⟂ z) gets in each section exactly the pieces and the
projection of `fem.mortar`, and M = thickness × the 2D M to rounding.

Exactness: the row sums Σ_j M_kj = ∫_cells ψ_{e,a} dA are polynomial integrals where the slave
face is affine (a triangle or a parallelogram, on a curved surface or not): the rigid-body patch
test holds to rounding. On flat interfaces π is affine and linear fields are transferred to
rounding. The entries themselves have a rational integrand (π along a varying normal), and on
bilinear quadrilaterals that are not parallelograms the inverse map is not polynomial either:
`QUAD_ORDER` is chosen so that these quadrature errors are ≤ 1e-13 relative on the test
geometries.

Rigid-body patch test: Σ_j M_kj = D_kk wherever the master covers the support of ψ_k;
`fem.mortar.patch_defect` measures it on the multiplier rows.

Folded masters (`nearest_hits`): where the normal lines of a slave face meet two master faces
(a master that folds back under it), the nearer one wins, as in 2D: the overlap of the two
cells is integrated again for the farther face with weight −1 (exact for two sheets; a master
folded twice under one slave face is refused).

Limits: a projected
slave face must be convex (true for any non-degenerate triangle and for quadrilaterals that are
not badly warped); master faces are cut along the straight chords between their nodes' images
(the images of their edges are curved where the normal field turns; the cells still tile the
slave face exactly, only the split between neighbouring master faces moves, by O(h³)). Where
a slave face's normal lines meet two master sheets (`nearest_hits`) the nearer by unsigned
distance wins, as in 2D: a slave that has penetrated a thin master deeper than half its
thickness is coupled to the far sheet.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .boundary import ENDS
from .elements import reference_element
from .mesh import Mesh as Mesh3D
from .surface3d import Surface, surface, triangle_rule

# Quadrature order of the face integrals (mass, normals): exact on affine faces; on non-planar
# quadrilaterals (|N| not polynomial) biorthogonality holds to 5e-14 relative at 7 % warp.
FACE_ORDER = 12
# Default order of the cell rule per face type (the larger of slave and master is used). The
# cell integrand is rational (the master point moves along the interpolated normal) and, on
# bilinear quadrilaterals that are not parallelograms, the inverse map is not polynomial either;
# at these orders M agrees with an order-24 rule to ≤ 1e-13 relative on the test geometries
# (tests/fem/test_mortar3d.py::test_cell_rule_default_is_converged).
QUAD_ORDER = {"triangle": 5, "quad": 10}


def rim_nodes(faces: np.ndarray) -> np.ndarray:
    """(r,) local indices of the nodes on the rim of a surface (edges of one face only)."""
    e = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)  # (n_f m, 2)
    key, count = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
    return np.unique(key[count == 1])


def dual_mass(s: Surface) -> sp.csr_matrix:
    """(m·n_f, k) the local slave block: ∫_e ψ_{e,a} φ_j dA = δ(j = node a of e) ∫_e φ_a dA."""
    rows = np.arange(s.faces.size)
    return sp.csr_matrix((s.face_weights.ravel(), (rows, s.faces.ravel())), (rows.size, s.size))


def multiplier_basis(s: Surface, carry: np.ndarray, ends: str = "merge") -> sp.csr_matrix:
    """Q (n_carry, m·n_f): ψ̃_k = Σ_(e,a) Q[k, m e + a] ψ_{e,a} for the nodes with carry True.

    Rows follow the carrying nodes in the order of `s.nodes`. A node that carries no multiplier
    (a crosspoint: on the rim of the contact surface and on a Dirichlet side) loses its
    functions; with ends="keep" they are dropped, with ends="merge" (Wohlmuth's boundary
    modification, the 3D form of `fem.boundary.multiplier_basis`) ψ_{e,b} of a dropped node b
    is shared equally by the carrying nodes of face e joined to b by a face edge, or by all
    carrying nodes of e if none is. Biorthogonality among carrying nodes is kept either way;
    "merge" also keeps Σ_k ψ̃_k = 1 on every face with a carrying node (constants in the
    multiplier space: the rigid-body and tied patch tests hold up to the rim).
    """
    if ends not in ENDS:
        raise ValueError(f"ends must be one of {ENDS}, got {ends!r}")
    carry = np.asarray(carry, dtype=bool)
    if carry.shape != (s.size,):
        raise ValueError(f"carry must have shape ({s.size},), got {carry.shape}")
    n_f, m = s.faces.shape
    row_of = np.cumsum(carry) - 1  # (k,)
    c = carry[s.faces]  # (n_f, m) carrying local nodes
    W = np.where(c[:, :, None], np.eye(m)[None], 0.0)  # (n_f, m targets, m sources)
    if ends == "merge":
        adj = np.eye(m, k=1) + np.eye(m, k=-1) + np.eye(m, k=m - 1) + np.eye(m, k=1 - m) > 0
        near = adj[None] & c[:, :, None]  # (n_f, m, m): target carries and is an edge neighbour
        share = np.where(near.any(axis=1, keepdims=True), near, c[:, :, None])  # (n_f, m, m)
        share &= ~c[:, None, :]  # only dropped sources are shared
        cnt = share.sum(axis=1, keepdims=True)  # (n_f, 1, m)
        W += np.where(share, 1.0 / np.maximum(cnt, 1), 0.0)
    f, t, a = np.nonzero(W)
    return sp.csr_matrix(
        (W[f, t, a], (row_of[s.faces[f, t]], m * f + a)), shape=(int(carry.sum()), m * n_f)
    )


@dataclass(frozen=True, eq=False)
class Mortar3D:
    """The segment-based dual mortar coupling of a slave and a master surface.

    slave, master : the two traces (`Surface`); global ids in slave.nodes, master.nodes.
    M : (m·n_f, k_m) csr, M[m e + a, j] = ∫_e ψ_{e,a} (φ_j^m ∘ π) dA (module docstring).
    coverage : (n_f,) fraction of each slave face's area mapped onto the master (0 … 1).
    n_cells : number of integration cells (non-empty clip polygons).
    """

    slave: Surface
    master: Surface
    M: sp.csr_matrix
    coverage: np.ndarray
    n_cells: int


def _cross2(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _planes(s: Surface) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Auxiliary planes of the slave faces: centres x0 (n_f, 3), unit normals n0 (n_f, 3) and
    in-plane axes E (n_f, 3, 2) with e1 × e2 = n0."""
    x0 = s.points[s.faces].mean(axis=1)  # (n_f, 3): ξ = 0 of a Q1 face, centroid of a P1 face
    n0 = s.normals[s.faces].mean(axis=1)  # (n_f, 3) φ_a(centre) = 1/m
    n0 /= np.linalg.norm(n0, axis=1)[:, None]
    axis = np.eye(3)[np.argmin(np.abs(n0), axis=1)]  # (n_f, 3) least aligned axis
    e1 = axis - np.einsum("fi,fi->f", axis, n0)[:, None] * n0
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    return x0, n0, np.stack([e1, np.cross(n0, e1)], axis=2)


def _face_normal(f: Surface) -> np.ndarray:
    """(n_f, 3) ∂x/∂ξ × ∂x/∂η at the face centre (outward, not normalised)."""
    X = f.points[f.faces]  # (n_f, m, 3)
    if f.face_type == "triangle":
        return np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    return np.cross(X[:, 1] + X[:, 2] - X[:, 0] - X[:, 3], X[:, 2] + X[:, 3] - X[:, 0] - X[:, 1])


def _candidates(s: Surface, m: Surface, x0, n0, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Slave/master face pairs (e, f) near each other and facing each other."""
    cs, cm = x0, m.points[m.faces].mean(axis=1)  # (n_fs, 3), (n_fm, 3)
    rs = np.linalg.norm(s.points[s.faces] - cs[:, None], axis=2).max(axis=1)  # (n_fs,)
    rm = np.linalg.norm(m.points[m.faces] - cm[:, None], axis=2).max()
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
        d_p = _cross2((B - A)[:, None], P - A[:, None])  # (n, K) ≥ 0: inside
        d_q = _cross2((B - A)[:, None], Q - A[:, None])
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


def _values(face_type: str, xi: np.ndarray) -> np.ndarray:
    """Shape function values (..., m) at reference points xi (..., 2)."""
    ref = reference_element(face_type)
    return ref.values(xi.reshape(-1, 2)).reshape(*xi.shape[:-1], ref.n_loc)


def _solve2(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """J⁻¹ r for stacks of 2×2 matrices J (..., 2, 2) and vectors r (..., 2) (Cramer)."""
    det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]  # (...,)
    x0 = J[..., 1, 1] * r[..., 0] - J[..., 0, 1] * r[..., 1]
    x1 = J[..., 0, 0] * r[..., 1] - J[..., 1, 0] * r[..., 0]
    return np.stack([x0, x1], axis=-1) / det[..., None]


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
        step = _solve2(np.stack([xs, xt], axis=-1), x - y)
        xi -= step
        if face_type == "triangle" or np.abs(step).max(initial=0.0) <= tol:
            return xi
    raise ValueError("inverse bilinear map did not converge (degenerate projected face)")


def _tangent_cross(face_type: str, X: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """N = ∂x/∂ξ × ∂x/∂η (n, q, 3) of faces X (n, m, 3) at reference points xi (n, q, 2)."""
    _, xs, xt = _evaluate(_coefficients(face_type, X), xi)
    return np.cross(xs, xt)


def _local(wt: np.ndarray, psi: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """(n_t, m_s, m_m) Σ_q wt ψ_a φ_b: the cell-triangle contributions to M."""
    return np.einsum("tq,tqa,tqb->tab", wt, psi, phi)


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


def cells(s: Surface, m: Surface, reach: float = 1.0):
    """The integration cells: clip polygons of every facing slave/master face pair.

    The slave face is projected orthogonally onto its auxiliary plane; each master node y is
    carried to the slave point x_s(ξ) whose interpolated normal line passes through it, and
    that point is projected onto the plane (so the cells follow the projection along the
    normal field, as the pieces of `fem.mortar` do in 2D).

    Returns (e, f, poly, count, x0, n0, E): slave face (n_c,), master face (n_c,), polygons
    (n_c, K, 2) in plane coordinates of the slave face's auxiliary plane (counterclockwise about
    n0), their vertex counts (n_c,) ≥ 3, and the planes of all slave faces (`_planes`).
    """
    x0, n0, E = _planes(s)
    e, f = _candidates(s, m, x0, n0, reach)
    Xs = s.points[s.faces[e]]  # (n_p, m_s, 3)
    S = np.einsum("pai,pij->paj", Xs - x0[e][:, None], E[e])  # (n_p, m_s, 2)
    Y = m.points[m.faces[f]]  # (n_p, m_m, 3)
    xi = inverse_map(s.face_type, S, np.einsum("pai,pij->paj", Y - x0[e][:, None], E[e]))
    xi = _rays(s.face_type, Xs, Y, xi, normals=s.normals[s.faces[e]])  # (n_p, m_m, 2)
    phi = _values(s.face_type, xi)  # (n_p, m_m, m_s)
    foot = np.einsum("pba,pai->pbi", phi, Xs)  # (n_p, m_m, 3) slave points below master nodes
    Mp = np.einsum("pai,pij->paj", foot - x0[e][:, None], E[e])  # (n_p, m_m, 2)
    Mp = Mp[:, ::-1]  # the master face is counterclockwise about −n0: reverse it
    poly, count = clip(Mp, np.full(e.size, Mp.shape[1]), S)
    keep = count >= 3
    return e[keep], f[keep], poly[keep], count[keep], x0, n0, E


def mortar_coupling3d(
    slave: Mesh3D,
    slave_part: str | Sequence[str],
    master: Mesh3D,
    master_part: str | Sequence[str],
    quad_order: int | None = None,
    reach: float = 1.0,
    face_order: int = FACE_ORDER,
) -> Mortar3D:
    """The segment-based dual mortar matrices of `slave_part` against `master_part`.

    quad_order : total degree of the collapsed Gauss rule on every cell triangle; default
        the larger `QUAD_ORDER` of the two face types (3 is exact for affine faces; bilinear
        quadrilaterals that are not parallelograms need more).
    reach : a master face is a candidate for a slave face e if their centres are at most
        (1 + reach)·r_e + r_max apart (r: the largest centre-to-node distance of a face).
    face_order : quadrature order of the face integrals (`fem.surface3d.surface`): a caller
        whose slave block D = diag(∫φ_k) comes from a surface of another order passes that
        order, so that D and the dual basis in M agree on non-planar faces.
    Cost: O(n_cells · q) with n_cells ≈ (slave faces) × (master faces per slave face).
    """
    s, m = surface(slave, slave_part, face_order), surface(master, master_part, face_order)
    return couple(s, m, quad_order, reach)


def _area(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """(n,) signed areas of polygons (n, K, 2) with counts (n,) (shoelace)."""
    i = np.arange(poly.shape[1])[None, :]  # (1, K)
    nxt = np.take_along_axis(poly, np.where(i + 1 < count[:, None], i + 1, 0)[..., None], 1)
    return 0.5 * np.where(i < count[:, None], _cross2(poly, nxt), 0.0).sum(axis=1)


def _hit_distance(s: Surface, m: Surface, e, f, y, x0, E) -> np.ndarray:
    """(n,) |x − π_f(x)| of the slave points x of faces e below plane points y (n, 2): how far
    along the interpolated normal the line meets master face f."""
    Xs, Xm = s.points[s.faces[e]], m.points[m.faces[f]]  # (n, m_s, 3), (n, m_m, 3)
    Ps = np.einsum("nai,nij->naj", Xs - x0[e][:, None], E[e])  # (n, m_s, 2)
    Pm = np.einsum("nai,nij->naj", Xm - x0[e][:, None], E[e])  # (n, m_m, 2)
    phi = _values(s.face_type, inverse_map(s.face_type, Ps, y[:, None]))  # (n, 1, m_s)
    x = np.einsum("nqa,nai->nqi", phi, Xs)  # (n, 1, 3)
    nrm = np.einsum("nqa,nai->nqi", phi, s.normals[s.faces[e]])
    xm = _rays(m.face_type, Xm, x, inverse_map(m.face_type, Pm, y[:, None]), dirs=nrm)
    hit = np.einsum("nqb,nbi->nqi", _values(m.face_type, xm), Xm)  # (n, 1, 3)
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


def nearest_hits(s: Surface, m: Surface, e, f, poly, count, x0, E, tol: float = 1e-12):
    """Overlap cells for a master that folds back under a slave face: where the cells of two
    master faces overlap on one slave face (the normal line meets both), the nearer face wins
    (as `fem.mortar` in 2D): the overlap polygon (the convex intersection of the two cells) is
    appended as a cell of the FARTHER face with weight −1, so that its integral is taken back.
    Nearer and farther are decided at the overlap's vertex mean (two sheets of one surface do
    not cross). Exact for two sheets; three cells over one point (a second fold) would be taken
    back twice: ValueError. Overlaps below tol × the slave face's area (cells of neighbouring
    master faces touching along an edge) are ignored.

    Returns (sign (n',), e, f, poly, count): the input cells with sign 1, then the overlaps.
    """
    sign = np.ones(e.size)
    oa, ob, op, oc = _overlapping(e, poly, count, s.areas[e], tol)
    if oa.size == 0:
        return sign, e, f, poly, count
    i = np.arange(op.shape[1])[None, :]
    ctr = (op * (i < oc[:, None])[..., None]).sum(axis=1) / oc[:, None]  # (n_o, 2)
    da = _hit_distance(s, m, e[oa], f[oa], ctr, x0, E)
    db = _hit_distance(s, m, e[ob], f[ob], ctr, x0, E)
    far = np.where(da <= db, ob, oa)  # (n_o,) the cell whose face is farther
    if _overlapping(far, op, oc, s.areas[e[far]], tol)[0].size:
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


def couple(s: Surface, m: Surface, quad_order: int | None = None, reach: float = 1.0) -> Mortar3D:
    """`mortar_coupling3d` on two traces."""
    if quad_order is None:
        quad_order = max(QUAD_ORDER[s.face_type], QUAD_ORDER[m.face_type])
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
    area2 = _cross2(a, b) * sign[c]  # (n_t,) twice the signed area (−: a taken-back overlap)
    pts, wq = triangle_rule(quad_order)  # (q, 2), (q,)
    y = ctr[c][:, None] + pts[None, :, :1] * a[:, None] + pts[None, :, 1:] * b[:, None]
    et, ft = e[c], f[c]  # (n_t,) slave and master face of each triangle
    Xs, Xm = s.points[s.faces[et]], m.points[m.faces[ft]]  # (n_t, m_s, 3), (n_t, m_m, 3)
    Ps = np.einsum("tai,tij->taj", Xs - x0[et][:, None], E[et])  # (n_t, m_s, 2)
    Pm = np.einsum("tai,tij->taj", Xm - x0[et][:, None], E[et])  # (n_t, m_m, 2)
    xs = inverse_map(s.face_type, Ps, y)  # (n_t, q, 2) slave points below y
    phi_s = _values(s.face_type, xs)  # (n_t, q, m_s)
    x = np.einsum("tqa,tai->tqi", phi_s, Xs)  # (n_t, q, 3)
    n = np.einsum("tqa,tai->tqi", phi_s, s.normals[s.faces[et]])  # (n_t, q, 3)
    xm = _rays(m.face_type, Xm, x, inverse_map(m.face_type, Pm, y), dirs=n)  # (n_t, q, 2)
    Ns = _tangent_cross(s.face_type, Xs, xs)  # (n_t, q, 3)
    ratio = np.linalg.norm(Ns, axis=2) / np.abs(np.einsum("tqi,ti->tq", Ns, n0[et]))
    wt = area2[:, None] * wq[None, :] * ratio  # (n_t, q) slave-surface weights
    psi = np.einsum("tqb,tab->tqa", phi_s, s.dual[et])  # (n_t, q, m_s)
    phi_m = _values(m.face_type, xm)  # (n_t, q, m_m)
    loc = _local(wt, psi, phi_m)  # (n_t, m_s, m_m)
    ms = s.faces.shape[1]
    rows = np.broadcast_to((ms * et[:, None] + np.arange(ms))[:, :, None], loc.shape)
    cols = np.broadcast_to(m.faces[ft][:, None, :], loc.shape)
    M = sp.csr_matrix((loc.ravel(), (rows.ravel(), cols.ravel())), shape=(s.faces.size, m.size))
    coverage = np.bincount(et, wt.sum(axis=1), minlength=s.faces.shape[0]) / s.areas
    return Mortar3D(s, m, M, coverage, n_cells)


def nodal_rows(mo: Mortar3D) -> sp.csr_matrix:
    """(k, k_m) M in nodal rows, Σ_a over the faces around each slave node: the rows of
    Q·M for `multiplier_basis(…, ends="keep")` with every node carrying, whose slave block is
    D = diag(weights)."""
    s = mo.slave
    P = sp.csr_matrix(
        (np.ones(s.faces.size), (s.faces.ravel(), np.arange(s.faces.size))),
        shape=(s.size, s.faces.size),
    )
    return (P @ mo.M).tocsr()


def covered_nodes(mo: Mortar3D, tol: float = 1e-9) -> np.ndarray:
    """(k,) bool: the master lies behind every face around the slave node (coverage ≥ 1 − tol);
    only such nodes can carry a multiplier whose rigid-body row is exact."""
    bad = mo.coverage < 1.0 - tol  # (n_f,)
    out = np.ones(mo.slave.size, dtype=bool)
    out[mo.slave.faces[bad].ravel()] = False
    return out
