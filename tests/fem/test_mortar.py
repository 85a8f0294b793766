"""Tests of fem.mortar: biorthogonality, consistency, linear reproduction, tied patch test."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from fem.boundary import trace
from fem.mapped import coons_block, reparametrise, segment
from fem.mortar import mortar_coupling
from fem.shapes import cradle, half_disc

LINEAR = [lambda x: np.ones(len(x)), lambda x: x[:, 0], lambda x: x[:, 1]]
LINEAR += [lambda x: 0.3 - 1.7 * x[:, 0] + 2.9 * x[:, 1]]


def random_knots(n, seed):
    steps = np.random.default_rng(seed).uniform(0.4, 1.6, n)  # (n,)
    return np.concatenate([[0.0], np.cumsum(steps) / steps.sum()])


def rectangle(y0, nx, ny, iface, seed):
    """[0, 1] × [y0, y0 + 1]; the side at y = 1 is the part "iface" with random node spacing."""
    c00, c10, c11, c01 = (0.0, y0), (1.0, y0), (1.0, y0 + 1), (0.0, y0 + 1)
    bottom, top = segment(c00, c10), segment(c11, c01)
    if iface == "top":
        top = reparametrise(top, random_knots(nx, seed))
    else:
        bottom = reparametrise(bottom, random_knots(nx, seed))
    names = {"bottom": "bottom", "right": "right", "top": "top", "left": "left"}
    names[iface] = "iface"
    return coons_block(bottom, segment(c10, c11), top, segment(c01, c00), nx, ny, names)


def stacked(n_lower=7, n_upper=5, seed=0):
    """Two non-matching rectangles meeting along y = 1: (lower, upper)."""
    return rectangle(0.0, n_lower, 3, "top", seed), rectangle(1.0, n_upper, 4, "bottom", seed + 1)


def paper(level, ends="keep"):
    d, c = half_disc(level=level), cradle(level=level)
    return d, c, mortar_coupling(d, "contact", c, "contact", ends=ends)


def dual_products(mesh, mo, merged):
    """(ns, ns) ∫ψ̃_i φ_j^s by 40-point Gauss on each slave segment, written out independently."""
    t = trace(mesh, "contact")
    g, w = np.polynomial.legendre.leggauss(40)
    s, w = 0.5 * (g + 1), 0.5 * w
    phi = np.stack([1 - s, s])  # (2, n_qp)
    psi = np.stack([2 - 3 * s, 3 * s - 1])  # (2, n_qp): 2φ_1 − φ_2, 2φ_2 − φ_1
    last = t.segments.shape[0] - 1
    out = np.zeros((t.size, t.size))
    for k, (a, b) in enumerate(t.segments):
        ps = psi.copy()
        if merged and k in (0, last):
            ps[:] = 1.0  # the neighbour's merged function is 1 on an end segment
            ps[0 if k == 0 else 1] = 0.0  # the end node carries no multiplier
        out[np.ix_([a, b], [a, b])] += t.lengths[k] * (ps * w) @ phi.T
    return out


@pytest.mark.parametrize("level", [0, 2])
def test_biorthogonality_keep(level):
    d, _, mo = paper(level)
    P = dual_products(d, mo, merged=False)
    np.testing.assert_allclose(P, np.diag(mo.D), atol=1e-15)
    np.testing.assert_allclose(mo.Ds.toarray(), P, atol=1e-15)
    np.testing.assert_allclose(mo.D, trace(d, "contact").weights, rtol=1e-15)


@pytest.mark.parametrize("level", [0, 2])
def test_merged_dual_functions(level):
    d, _, mo = paper(level, ends="merge")
    P = dual_products(d, mo, merged=True)
    np.testing.assert_allclose(mo.Ds.toarray(), P[mo.active], atol=1e-15)
    assert not mo.active[[0, -1]].any() and mo.active[1:-1].all()
    t = trace(d, "contact")
    np.testing.assert_allclose(mo.Ds[0, 0], 0.5 * t.lengths[0], rtol=1e-14)  # ∫_end-seg 1·φ_end
    np.testing.assert_allclose(mo.D[mo.active], t.weights[mo.active], rtol=1e-14)
    assert (mo.D[~mo.active] == 0).all() and mo.M[[0, -1]].nnz == 0


@pytest.mark.parametrize("ends", ["keep", "merge"])
@pytest.mark.parametrize("level", [0, 1, 2, 3])
def test_constants_are_reproduced_on_the_arc(level, ends):
    _, _, mo = paper(level, ends)
    np.testing.assert_allclose(mo.coverage, 1.0, atol=1e-14)
    row_M = np.asarray(mo.M_active.sum(axis=1)).ravel()  # (n_active,)
    row_D = np.asarray(mo.Ds.sum(axis=1)).ravel()
    assert np.abs(row_M - row_D).max() <= 1e-12 * row_D.max()
    if ends == "keep":
        np.testing.assert_allclose(mo.M @ np.ones(mo.M.shape[1]) / mo.D, 1.0, atol=1e-12)


def test_linear_functions_converge_at_rate_two_on_the_arc():
    """D⁻¹M f(x_m) − f(x_s) = O(h²) on the arc: the two polylines are different chords.

    The error per unit |∇f| is compared with the sum of the two chord sagittas r(1 − cos(Δθ/2))
    (a natural scale for the distance between the polylines, not a proven bound).
    """
    errs, sagittas = [], []
    for level in range(4):
        d, c, mo = paper(level)
        xs, xm = d.points[mo.slave_nodes], c.points[mo.master_nodes]
        grads = [1.0, 1.0, np.hypot(1.7, 2.9)]
        errs.append(
            max(
                np.abs(mo.M @ f(xm) / mo.D - f(xs)).max() / gr
                for f, gr in zip(LINEAR[1:], grads, strict=True)
            )
        )
        dth = np.pi / 2 / np.array([8, 12]) / 2**level
        sagittas.append(np.sum(1 - np.cos(dth / 2)))
    rate = -np.polyfit(np.arange(4), np.log2(errs), 1)[0]
    assert 1.9 < rate < 2.1, (errs, rate)
    assert (np.array(errs) < np.array(sagittas)).all(), (errs, sagittas)


def test_matching_curved_meshes_give_m_equal_to_d():
    """Identical node sets on the arc: π is the identity, so M = diag(D) exactly."""
    d, c = half_disc(level=1), cradle(n_contact=8, level=1)
    mo = mortar_coupling(d, "contact", c, "contact")
    xs, xm = d.points[mo.slave_nodes], c.points[mo.master_nodes]
    np.testing.assert_allclose(xs, xm[::-1], atol=1e-15)
    np.testing.assert_allclose(mo.M.toarray()[:, ::-1], np.diag(mo.D), atol=1e-13)


@pytest.mark.parametrize("level", [0, 2])
def test_coupling_respects_the_mirror_symmetry_of_the_paper_geometry(level):
    """The example is symmetric about x = 0; so is M (slave i ↔ ns−1−i, master j ↔ nm−1−j).

    This is sensitive to the projection direction: a normal that is not interpolated along
    the slave segment breaks the symmetry.
    """
    d, c, mo = paper(level)
    xs = d.points[mo.slave_nodes]
    np.testing.assert_allclose(xs[::-1] * [-1, 1], xs, atol=1e-14)
    M = mo.M.toarray()
    np.testing.assert_allclose(M[::-1, ::-1], M, atol=1e-13 * M.max())


@pytest.mark.parametrize("slave_is_upper", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_linear_functions_are_exact_on_a_straight_interface(slave_is_upper, seed):
    lower, upper = stacked(seed=seed)
    (s, m) = (upper, lower) if slave_is_upper else (lower, upper)
    mo = mortar_coupling(s, "iface", m, "iface")
    mm = mortar_coupling(s, "iface", m, "iface", ends="merge")
    xs, xm = s.points[mo.slave_nodes], m.points[mo.master_nodes]
    assert np.ptp(np.diff(np.sort(xs[:, 0]))) > 0.05  # the spacing is really non-uniform
    np.testing.assert_allclose(mo.coverage, 1.0, atol=1e-14)
    for f in LINEAR:
        np.testing.assert_allclose(mo.M @ f(xm) / mo.D, f(xs), atol=1e-12, rtol=0)
        np.testing.assert_allclose(mm.M_active @ f(xm), mm.Ds @ f(xs), atol=1e-12, rtol=0)


def test_uncovered_slave_region_is_reported():
    """A master covering only x ∈ [0.3, 1] of the slave: the row sums miss exactly 0.3."""
    _, upper = stacked()
    c = [(0.3, 0.0), (1.0, 0.0), (1.0, 1.0), (0.3, 1.0)]
    short = coons_block(
        segment(c[0], c[1]), segment(c[1], c[2]), segment(c[2], c[3]), segment(c[3], c[0]), 4, 2,
        {"top": "iface"},
    )  # fmt: skip
    mo = mortar_coupling(upper, "iface", short, "iface")
    assert np.isclose(mo.M.sum(), 0.7, atol=1e-14)  # Σ_i ψ_i = 1: ∫ over the covered part
    ts = trace(upper, "iface")
    x0 = upper.points[ts.nodes[ts.segments]][:, :, 0]  # (n_seg, 2)
    expected = np.clip((x0.max(1) - 0.3) / (x0.max(1) - x0.min(1)), 0, 1)
    np.testing.assert_allclose(mo.coverage, expected, atol=1e-14)
    assert (mo.coverage < 1).any()


def test_back_facing_master_is_ignored():
    """The master's part with the same orientation as the slave's does not face it."""
    lower, upper = stacked()
    mo = mortar_coupling(upper, "iface", upper, "iface")
    assert mo.M.nnz == 0 and (mo.coverage == 0).all()


def test_bad_arguments():
    lower, upper = stacked()
    with pytest.raises(ValueError, match="ends"):
        mortar_coupling(upper, "iface", lower, "iface", ends="drop")
    one = coons_block(
        segment((0, 1), (1, 1)), segment((1, 1), (1, 2)), segment((1, 2), (0, 2)),
        segment((0, 2), (0, 1)), 1, 1, {"bottom": "iface"},
    )  # fmt: skip
    with pytest.raises(ValueError, match="merge"):
        mortar_coupling(one, "iface", lower, "iface", ends="merge")


# ---------------------------------------------------------------- test-only Q1 Laplace assembly


def _q1_laplace(mesh):
    """TEST-ONLY: the Q1 stiffness ∫∇u·∇v with 2×2 Gauss, vectorised over cells."""
    g = np.array([-1.0, 1.0]) / np.sqrt(3.0)
    xi, eta = np.meshgrid(g, g, indexing="ij")
    xi, eta = xi.ravel(), eta.ravel()  # (4,) points, weights 1
    sx, sy = np.array([-1, 1, 1, -1]), np.array([-1, -1, 1, 1])
    dN = 0.25 * np.stack(
        [sx[None] * (1 + sy[None] * eta[:, None]), sy[None] * (1 + sx[None] * xi[:, None])], -1
    )  # (n_qp, 4, 2) reference gradients
    X = mesh.points[mesh.cells]  # (n_cells, 4, 2)
    J = np.einsum("cki,qkj->cqij", X, dN)  # (n_cells, n_qp, 2, 2), J_ij = ∂x_i/∂ξ_j
    det = np.linalg.det(J)  # (n_cells, n_qp)
    G = np.einsum("qkj,cqji->cqki", dN, np.linalg.inv(J))  # (n_cells, n_qp, 4, 2)
    Ke = np.einsum("cqai,cqbi,cq->cab", G, G, det)  # (n_cells, 4, 4)
    rows = np.repeat(mesh.cells, 4, axis=1)  # (n_cells, 16)
    cols = np.tile(mesh.cells, (1, 4))
    n = mesh.n_nodes
    return sp.csr_matrix((Ke.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n))


def _select(nodes, n):
    """(len(nodes), n) the 0/1 matrix picking the trace nodes out of all mesh nodes."""
    k = nodes.size
    return sp.csr_matrix((np.ones(k), (np.arange(k), nodes)), shape=(k, n))


def _tied_solve(slave, master, ends, dirichlet_parts, u_exact):
    """Solve the mortar-tied Laplace problem, Dirichlet data u_exact on the given parts.

    Returns (u, u_exact at the nodes, multipliers); slave dofs first, then master dofs.
    """
    mo = mortar_coupling(slave, "iface", master, "iface", ends=ends)
    ns_all = slave.n_nodes
    K = sp.block_diag([_q1_laplace(slave), _q1_laplace(master)]).tocsr()  # (N, N)
    X = np.vstack([slave.points, master.points])  # (N, 2)
    N = X.shape[0]
    B = sp.hstack(
        [
            mo.Ds @ _select(mo.slave_nodes, ns_all),
            -mo.M_active @ _select(mo.master_nodes, N - ns_all),
        ]
    ).tocsr()  # (n_active, N): B u = Ds u_s − M u_m
    fixed = np.unique(
        np.concatenate(
            [slave.boundary_nodes(p) for p in dirichlet_parts if p in slave.boundaries]
            + [ns_all + master.boundary_nodes(p) for p in dirichlet_parts if p in master.boundaries]
        )
    )  # corners belong to two parts
    free = np.setdiff1d(np.arange(N), fixed)
    u = np.zeros(N)
    u[fixed] = u_exact(X[fixed])
    A = sp.bmat([[K[free][:, free], B[:, free].T], [B[:, free], None]]).tocsc()
    rhs = np.concatenate([-K[free][:, fixed] @ u[fixed], -B[:, fixed] @ u[fixed]])
    sol = spla.spsolve(A, rhs)
    u[free] = sol[: free.size]
    return u, u_exact(X), sol[free.size :]


@pytest.mark.parametrize("seed", [0, 3])
def test_tied_patch_test_merge_reproduces_any_linear_field(seed):
    lower, upper = stacked(seed=seed)
    f = LINEAR[3]
    u, exact, lam = _tied_solve(upper, lower, "merge", ["top", "bottom", "left", "right"], f)
    np.testing.assert_allclose(u, exact, atol=1e-10, rtol=0)
    np.testing.assert_allclose(lam, 2.9, rtol=1e-10)  # λ = −∂u/∂n_s, n_s = (0, −1)


@pytest.mark.parametrize("seed", [0, 3])
def test_tied_patch_test_keep_reproduces_a_vertical_linear_field(seed):
    """ends="keep", all interface nodes free: Dirichlet on top/bottom, natural on the sides."""
    lower, upper = stacked(seed=seed)
    f = lambda x: 0.3 + 2.9 * x[:, 1]  # noqa: E731  zero flux through the sides
    u, exact, lam = _tied_solve(upper, lower, "keep", ["top", "bottom"], f)
    np.testing.assert_allclose(u, exact, atol=1e-10, rtol=0)
    np.testing.assert_allclose(lam, 2.9, rtol=1e-10)
