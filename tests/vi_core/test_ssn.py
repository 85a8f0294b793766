"""Semismooth Newton: closed-form solutions, condensed vs full steps, unit invariance."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from vi_core import Ball, Box, Free, MixedVI, NonNegative, product, solve
from vi_core.linalg import pardiso_available

seeds = st.integers(0, 2**32 - 1)


def _random_set(rng, m):
    kind = rng.integers(0, 4)
    if kind == 0:
        return product(
            Free(m // 2), Box(-rng.uniform(0, 1, m - m // 2), rng.uniform(0, 1, m - m // 2))
        )
    if kind == 1:
        return NonNegative(m)
    if kind == 2:
        return Ball(rng.uniform(0, 1, m // 2), 2) if m % 2 == 0 else Box(-1.0, 1.0, size=m)
    return product(Box(-rng.uniform(0, 1, m), rng.uniform(0, 1, m)))


def _random_vi(rng, n=30, m=8, skew=1.0, mortar=True):
    M = rng.standard_normal((n, n))
    A = (
        M @ M.T / n
        + np.eye(n)
        + skew * (lambda S: S - S.T)(rng.standard_normal((n, n))) / np.sqrt(n)
    )
    if mortar:  # dual-mortar-like B: a private diagonal block plus coupling to other columns
        B = np.zeros((m, n))
        B[np.arange(m), np.arange(m)] = rng.uniform(0.5, 2, m)
        B[:, m : 2 * m] = -0.3 * rng.standard_normal((m, m))
    else:
        B = rng.standard_normal((m, n))
    f = 10 * rng.standard_normal(n)
    return MixedVI(sp.csr_matrix(A), sp.csr_matrix(B), f, _random_set(rng, m))


@given(seeds)
def test_identity_problem_has_projection_solution(seed):
    """A = I, B = I: λ = P_Λ(f), u = f − λ for every set type."""
    rng = np.random.default_rng(seed)
    m = 2 * int(rng.integers(1, 6))
    Lam = _random_set(rng, m)
    f = 3 * rng.standard_normal(m)
    vi = MixedVI(sp.identity(m), sp.identity(m), f, Lam)
    sol = solve(vi, "ssn", tol=1e-12)
    assert sol.converged
    np.testing.assert_allclose(sol.lam, Lam.project(f), atol=1e-11)
    np.testing.assert_allclose(sol.u, f - Lam.project(f), atol=1e-11)


@given(seeds)
def test_condensed_and_full_newton_agree(seed):
    rng = np.random.default_rng(seed)
    vi = _random_vi(rng)
    a = solve(vi, "ssn", tol=1e-11, condense=True)
    b = solve(vi, "ssn", tol=1e-11, condense=False)
    assert a.converged and b.converged
    assert a.info["condensed"] and not b.info["condensed"]
    np.testing.assert_allclose(a.u, b.u, rtol=1e-8, atol=1e-9 * np.abs(b.u).max())
    np.testing.assert_allclose(a.lam, b.lam, rtol=1e-8, atol=1e-9 * max(np.abs(b.lam).max(), 1))


@given(seeds)
def test_condensation_picks_among_extra_private_columns(seed):
    """Each row pair owns 4 private columns (a slave and a master node tied to one slave node
    only, as next to a mortar crosspoint), two of them nearly parallel: detect keeps a
    well-conditioned pair, and the condensed steps agree with the full ones."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    n_pairs, n = 4, 40
    B = np.zeros((2 * n_pairs, n))
    for k in range(n_pairs):
        rows, cols = [2 * k, 2 * k + 1], 4 * k + np.arange(4)
        v = rng.standard_normal(2)
        B[np.ix_(rows, cols[:2])] = np.column_stack([v, v * (1 + 1e-12)])  # rank one
        B[np.ix_(rows, cols[2:])] = rng.uniform(0.5, 2, (2, 2)) + 2 * np.eye(2)
    B[:, 30:] = 0.3 * rng.standard_normal((2 * n_pairs, 10))  # shared columns
    cond = Condensation.detect(sp.csr_matrix(B))
    assert cond is not None and np.linalg.cond(cond.D.toarray()) < 1e4
    vi = _random_vi(rng, n=n, m=2 * n_pairs)
    vi = MixedVI(vi.A, sp.csr_matrix(B), vi.f, vi.Lambda)
    a = solve(vi, "ssn", tol=1e-11, condense=True)
    b = solve(vi, "ssn", tol=1e-11, condense=False)
    assert a.converged and b.converged and a.info["condensed"]
    np.testing.assert_allclose(a.u, b.u, rtol=1e-8, atol=1e-9 * np.abs(b.u).max())


@given(seeds)
def test_general_b_and_nonsymmetric_a_converge(seed):
    rng = np.random.default_rng(seed)
    vi = _random_vi(rng, mortar=False, skew=2.0)
    sol = solve(vi, "ssn", tol=1e-10)
    assert sol.converged, sol.history
    r = vi.residual(sol.u, sol.lam)
    assert r.relative <= 1e-10
    assert vi.Lambda.contains(sol.lam, 1e-9 * max(1.0, np.abs(sol.lam).max()))


@given(seeds)
def test_unit_change_gives_the_same_physical_answer(seed):
    """Rescaling unknowns and equations (a change of units) changes nothing physical."""
    rng = np.random.default_rng(seed)
    vi = _random_vi(rng)
    su = 10.0 ** rng.integers(-8, 9, vi.n)  # u = su ⊙ u_new
    sl = 10.0 ** rng.integers(-6, 7)  # one unit for all multipliers (sets scale uniformly)
    Su = sp.diags(su)
    vi2 = MixedVI(
        Su @ vi.A @ Su, vi.B @ Su * (1 / 1.0), su * vi.f, vi.Lambda, gap=vi.gap
    )  # same λ units
    vi3 = MixedVI(vi.A, vi.B * sl, vi.f, vi.Lambda.scaled(np.full(vi.m, sl)), gap=vi.gap * sl)
    a = solve(vi, "ssn", tol=1e-11)
    b = solve(vi2, "ssn", tol=1e-11)
    c = solve(vi3, "ssn", tol=1e-11)
    assert a.converged and b.converged and c.converged
    np.testing.assert_allclose(b.u * su, a.u, rtol=1e-7, atol=1e-8 * np.abs(a.u).max())
    np.testing.assert_allclose(b.lam, a.lam, rtol=1e-7, atol=1e-8 * max(np.abs(a.lam).max(), 1))
    np.testing.assert_allclose(
        c.lam * sl, a.lam, rtol=1e-7, atol=1e-8 * max(np.abs(a.lam).max(), 1)
    )
    # the reported residual is the residual of the returned pair (up to rounding)
    assert abs(a.residual - vi.residual(a.u, a.lam).relative) <= 1e-13


def test_history_starts_at_initial_guess_and_ends_at_residual():
    rng = np.random.default_rng(3)
    vi = _random_vi(rng)
    sol = solve(vi, "ssn")
    assert sol.history[0] == vi.residual(np.zeros(vi.n), np.zeros(vi.m)).relative
    assert sol.history[-1] == sol.residual
    assert len(sol.history) == sol.iterations + 1


@given(seeds)
def test_equilibrated_problem_has_unit_diagonal_and_unit_rows(seed):
    rng = np.random.default_rng(seed)
    vi = _random_vi(rng)
    su = 10.0 ** rng.integers(-8, 9, vi.n)
    vi = MixedVI(sp.diags(su) @ vi.A @ sp.diags(su), 1e-7 * vi.B @ sp.diags(su), vi.f, vi.Lambda)
    e = vi.equilibrated
    np.testing.assert_allclose(e.A.diagonal(), 1.0, rtol=1e-12)
    rows = np.sqrt(np.asarray(e.B.multiply(e.B).sum(axis=1)).ravel())
    sizes = vi.Lambda.block_sizes()
    if (sizes == 1).all():
        np.testing.assert_allclose(rows, 1.0, rtol=1e-12)
    else:
        assert 0.1 < rows.min() and rows.max() < 10


@pytest.mark.parametrize("condense", [True, False])
def test_newton_matrix_pattern_is_fixed_while_the_active_set_changes(condense, monkeypatch):
    """The README's claim: one sparsity pattern for every Newton matrix of a solve (explicit
    zeros kept), so a direct solver can reuse its analysis. Mutation: without storing on the
    fixed pattern the nonzero count follows the active set (condensed: the S rows no longer fit
    the kept matrix)."""
    import vi_core.ssn as ssn_module
    from problems.plugins.contact import plane as pc
    from problems.scene import load_scene

    vi = pc.build(load_scene("paper_two_body"), 1).vi
    sol = solve(vi, "ssn", condense=condense, linear_solver="splu")
    assert sol.converged and sol.iterations >= 3 and len(sol.info["newton_nnz"]) == 1
    monkeypatch.setattr(ssn_module, "_on_pattern", lambda M, pattern: sp.csr_matrix(M))
    if condense:  # K is kept and its S rows overwritten in place: off the pattern they do not fit
        with pytest.raises(ValueError, match="shape mismatch"):
            solve(vi, "ssn", condense=condense, linear_solver="splu")
        return
    sol = solve(vi, "ssn", condense=condense, linear_solver="splu")
    assert len(sol.info["newton_nnz"]) > 1


@pytest.mark.skipif(not pardiso_available(), reason="pypardiso not installed (extra [fast])")
def test_pardiso_analyses_once_per_solve():
    from problems.plugins.contact import plane as pc
    from problems.scene import load_scene

    vi = pc.build(load_scene("paper_two_body"), 1).vi
    a = solve(vi, "ssn", linear_solver="pardiso")
    b = solve(vi, "ssn", linear_solver="splu")
    assert a.iterations >= 3 and a.info["symbolic_analyses"] == 1
    assert b.info["symbolic_analyses"] == b.iterations
    assert np.linalg.norm(a.lam - b.lam) <= 1e-12 * np.linalg.norm(b.lam)


def _frame_rows_b(rng, k: int, n: int) -> sp.csr_matrix:
    """B of k 3D contact nodes: rows n_i (0 … k−1), then (t1_i, t2_i) pairs, each node's block
    W_i·Q_i on its 3 displacement columns, Q_i a right-handed frame; in most frames t2 lies in
    a coordinate plane, so one displacement component has an exact zero in the t2 row (its
    column touches 2 of the node's 3 rows); every row also reaches the shared master columns."""
    B = np.zeros((3 * k, n))
    for i in range(k):
        c = rng.uniform(0, 2 * np.pi)
        t2 = np.array([np.cos(c), np.sin(c), 0.0])
        if rng.uniform() < 0.25:  # a generic frame: no exact zero
            t2 = rng.standard_normal(3)
            t2 /= np.linalg.norm(t2)
        v = rng.standard_normal(3)
        nn = v - (v @ t2) * t2
        nn /= np.linalg.norm(nn)
        Q = np.array([nn, np.cross(t2, nn), t2])  # rows n, t1, t2
        Q = Q[:, rng.permutation(3)]  # the zero in any component
        rows = [i, k + 2 * i, k + 2 * i + 1]
        B[np.ix_(rows, 3 * i + np.arange(3))] = rng.uniform(0.5, 2) * Q
    B[:, 3 * k :] = 0.2 * rng.standard_normal((3 * k, n - 3 * k))  # master side: shared
    return sp.csr_matrix(B)


@given(seeds)
def test_condensation_of_3d_frames_with_exact_zeros(seed):
    """3D contact nodes whose frame has an exact zero (a tangent in a coordinate plane, rows
    of a node not contiguous): detect groups each node's 3 columns with its 3 rows, D^{-T} is
    the inverse transpose of D, and condensed steps agree with full ones (paper_two_body_extruded
    level 1 and spherical_cap levels 0, 1 were not condensable before)."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    k, n = 4, 24
    B = _frame_rows_b(rng, k, n)
    cond = Condensation.detect(B)
    assert cond is not None
    assert np.array_equal(np.sort(cond.S), np.arange(3 * k))
    # blocks W·Q with Q orthogonal, W ∈ [0.5, 2]: condition ≤ 4
    np.testing.assert_allclose((cond.Dt_inv @ cond.D.T).toarray(), np.eye(3 * k), atol=1e-12)
    vi = _random_vi(rng, n=n, m=3 * k)
    Lam = product(Free(k), Ball(rng.uniform(0.1, 1, k), 2))
    vi = MixedVI(vi.A, B, vi.f, Lam)
    a = solve(vi, "ssn", tol=1e-11, condense=True)
    b = solve(vi, "ssn", tol=1e-11, condense=False)
    assert a.converged and b.converged and a.info["condensed"]
    np.testing.assert_allclose(a.u, b.u, rtol=1e-8, atol=1e-9 * np.abs(b.u).max())


def test_condensation_without_subset_merge_fails_on_3d_frames(monkeypatch):
    """Mutation: grouping columns by their exact row set only (the rule before) finds no
    condensation of such a B — the test above exercises the merge."""
    from vi_core import ssn as ssn_module

    B = _frame_rows_b(np.random.default_rng(3), 4, 20)
    assert ssn_module.Condensation.detect(B) is not None
    monkeypatch.setattr(ssn_module, "_merge_subsets", lambda groups: groups)
    assert ssn_module.Condensation.detect(B) is None


def test_condensation_does_not_chain_two_nodes():
    """A small column touching the normal rows of two nodes does not merge their groups: each
    node keeps its own 3 × 3 block (D has no entry between the two nodes)."""
    from vi_core.ssn import Condensation

    B = _frame_rows_b(np.random.default_rng(5), 2, 12).toarray()
    B[:, 6:] = 0.0
    B[[0, 1], 6] = 3.0  # a strong master column coupled to the two nodes' normal rows only
    B[:, 7:] = 0.2  # shared columns
    cond = Condensation.detect(sp.csr_matrix(B))
    assert cond is not None and 6 not in cond.S
    D = cond.D.toarray()
    node = np.array([0, 1, 0, 0, 1, 1])  # the node of each row: n0, n1, t1_0, t2_0, t1_1, t2_1
    assert np.all(D[node[:, None] != node[None, :]] == 0)


@given(seeds)
def test_condensation_keeps_square_groups_inside_master_row_sets(seed):
    """One row per node (a scalar problem): each row has a private column, and master columns
    reach two neighbouring rows each. A private column's row set {j} lies inside a master
    column's {j−1, j} but is square on its own: it stays its own group (merging it into the
    master's set — the subset merge without the deficiency condition — leaves no condensation)."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    k = int(rng.integers(3, 12))
    rows = np.arange(k)
    cols = np.concatenate([rows, rows + k, (rows + 1) % k + k])
    vals = np.concatenate([rng.uniform(0.5, 2.0, k), -rng.uniform(0.1, 1.0, 2 * k)])
    B = sp.csr_matrix((vals, (np.tile(rows, 3), cols)), shape=(k, 3 * k))
    cond = Condensation.detect(B)
    assert cond is not None and np.array_equal(cond.S, rows)


def _sparse_b(rng) -> sp.csr_matrix:
    """A random sparse B (m ≤ 6 rows, up to 14 columns; every third a private diagonal added)
    without any structure of contact rows: small column row sets that overlap, nest and chain."""
    m = int(rng.integers(1, 7))
    n = int(rng.integers(m, 15))
    B = rng.standard_normal((m, n)) * (rng.uniform(size=(m, n)) < rng.uniform(0.1, 0.6))
    if rng.uniform() < 0.3:
        B[:, :m] += np.diag(rng.uniform(0.5, 2.0, m))
    return sp.csr_matrix(B)


def _condensation_defects(B: sp.csr_matrix, cond) -> list[str]:
    """What a condensation of B gets wrong against its definition: S (one column per row,
    distinct) and R partition the columns, D = B[:, S], and Dt_inv is D^{-T}."""
    m, n = B.shape
    out = []
    if len(set(cond.S.tolist())) != m or not np.array_equal(
        np.sort(np.concatenate([cond.S, cond.R])), np.arange(n)
    ):
        out.append("S, R not a partition")
    D = B[:, cond.S].toarray()
    if not np.allclose(cond.D.toarray(), D, rtol=0, atol=0):
        out.append("D is not B[:, S]")
    if np.abs(cond.Dt_inv.toarray() @ D.T - np.eye(m)).max() > 1e-8 * np.linalg.cond(D):
        out.append("Dt_inv is not D^{-T}")
    return out


@given(seeds)
def test_any_condensation_found_is_exact(seed):
    """Whatever row set rule detect applies, a condensation it returns is exact for any sparse
    B (not only contact rows): D = B[:, S] with D^{-T}, and condensed steps agree with full
    ones. (Random B: about 40 % of them have a condensation.)"""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    B = _sparse_b(rng)
    cond = Condensation.detect(B)
    if cond is None:
        return
    assert _condensation_defects(B, cond) == []
    m, n = B.shape
    vi = _random_vi(rng, n=n, m=m, mortar=False)
    vi = MixedVI(vi.A, B, vi.f, Box(-rng.uniform(0, 1, m), rng.uniform(0, 1, m)))
    a = solve(vi, "ssn", tol=1e-11, condense=True)
    b = solve(vi, "ssn", tol=1e-11, condense=False)
    assert a.converged and b.converged and a.info["condensed"]
    np.testing.assert_allclose(a.u, b.u, rtol=1e-7, atol=1e-8 * np.abs(b.u).max())
    np.testing.assert_allclose(a.lam, b.lam, rtol=1e-7, atol=1e-8 * max(np.abs(b.lam).max(), 1))


def test_a_transposed_block_inverse_is_seen_by_the_definition_check(monkeypatch):
    """Mutation: the blocks of Dt_inv inverted without the transpose (D^{-1} for D^{-T}, the
    same on 1 × 1 and symmetric blocks): the definition check of the test above reports it on
    random B."""
    from vi_core.ssn import Condensation

    inv = np.linalg.inv
    seen = 0
    for seed in range(300):
        B = _sparse_b(np.random.default_rng(seed))
        with monkeypatch.context() as mp:
            mp.setattr(np.linalg, "inv", lambda a: inv(a).T)  # inv(block.T) → inv(block)
            cond = Condensation.detect(B)
        seen += cond is not None and "Dt_inv is not D^{-T}" in _condensation_defects(B, cond)
    assert seen >= 5


def _tie_defects(seed: int) -> tuple[float, float, float]:
    """`tied_start` on 3D contact nodes (normal rows Free with a gap, tangential pairs a Ball
    without, λ0 inside the ball at some nodes, outside at others): the largest |B u − gap| on
    the tied rows, the largest change of B u on the others, the largest change of u off the
    slave columns."""
    from vi_core.ssn import Condensation, tied_start

    rng = np.random.default_rng(seed)
    k, n = 4, 24
    B = _frame_rows_b(rng, k, n)
    radius = rng.uniform(0.5, 1.0, k)
    gap = np.concatenate([rng.standard_normal(k), np.zeros(2 * k)])
    vi = MixedVI(sp.identity(n), B, np.zeros(n), product(Free(k), Ball(radius, 2)), gap=gap)
    lam0 = rng.standard_normal(3 * k)
    t = lam0[k:].reshape(k, 2)
    inside = rng.random(k) < 0.5
    t *= (np.where(inside, 0.5, 2.0) * radius / np.linalg.norm(t, axis=1))[:, None]
    tied = np.concatenate([np.ones(k, bool), np.repeat(inside, 2)])  # (3k,)
    u0 = rng.standard_normal(n)
    u = tied_start(vi, u0, lam0)
    off = np.setdiff1d(np.arange(n), Condensation.detect(B).S)
    return (
        float(np.abs(B @ u - vi.gap)[tied].max()),
        float(np.abs(B @ (u - u0))[~tied].max(initial=0.0)),
        float(np.abs(u - u0)[off].max()),
    )


@given(seeds)
def test_tied_start_ties_the_predicted_rows_only(seed):
    """u moves on the slave columns only, B u = gap on the rows λ0 predicts tied (normal rows,
    tangential pairs strictly inside the ball), the other rows of B u unchanged."""
    tied, others, off = _tie_defects(seed)
    assert tied <= 1e-12 and others <= 1e-12 and off == 0.0


def test_tied_start_leaves_rows_apart_by_a_gap():
    """Unilateral rows: a rounding-level λ0 > 0 across a gap is not touching (the first Newton
    step from λ0 does not tie it), a clear λ0 is: only that row is closed."""
    from vi_core.ssn import tied_start

    B = sp.csr_matrix(np.array([[1.0, 0.0, -0.5], [0.0, 1.0, -0.5]]))
    vi = MixedVI(sp.identity(3), B, np.zeros(3), NonNegative(2), gap=np.array([0.1, 0.1]))
    u = tied_start(vi, np.zeros(3), np.array([1e-13, 1.0]))
    np.testing.assert_allclose(B @ u, [0.0, 0.1], atol=1e-15)


def test_tied_start_check_catches_a_transposed_inverse(monkeypatch):
    """The mutation: D^{-T} where D^{-1} belongs (the blocks W·Q are not symmetric)."""
    import vi_core.ssn as ssn_module

    detect = ssn_module.Condensation.detect

    def transposed(B):
        c = detect(B)
        return ssn_module.Condensation(S=c.S, R=c.R, D=c.D, Dt_inv=sp.csr_matrix(c.Dt_inv.T))

    monkeypatch.setattr(ssn_module.Condensation, "detect", staticmethod(transposed))
    assert max(_tie_defects(s)[0] for s in range(5)) > 1e-3


def test_tied_start_ties_the_rows_it_is_given():
    """With `tied` given, those rows are closed whatever J(λ0) says: here λ0 of the second
    row lies on the ball's boundary (J counts it inside, tied), and the caller frees it."""
    from vi_core.ssn import tied_start

    B = sp.csr_matrix(np.array([[1.0, 0.0, -0.5], [0.0, 1.0, -0.5]]))
    vi = MixedVI(sp.identity(3), B, np.zeros(3), Ball(np.array([1.0]), 2), gap=np.zeros(2))
    u0 = np.array([0.3, 0.2, 0.1])
    lam0 = np.array([0.6, 0.8])  # |λ0| = 1: on the boundary
    np.testing.assert_allclose(B @ tied_start(vi, u0, lam0), [0.0, 0.0], atol=1e-15)
    u = tied_start(vi, u0, lam0, np.array([True, False]))
    np.testing.assert_allclose(B @ u, [0.0, 0.15], atol=1e-15)


# faults injected into ssn.damped_step's source: (text, replacement)
DAMPING_FAULTS = {
    "no_armijo": ("cand <= (1.0 - 1e-4 * t) * res", "True"),
    "last_not_best": ("best is None or cand < best[1]", "True"),
    "no_floor": ("t < 1.0 / 64", "t < 1.0 / 4"),
}


@pytest.mark.parametrize("fault", [None, *DAMPING_FAULTS])
def test_damped_step_halves_to_the_best_trial(fault):
    """The shared step of the serial and PETSc loops (`ssn.damped_step`): on a residual that
    is smallest at t = 0.2, t is halved to 1/4 (the first trial meeting the Armijo test); when
    no trial meets it, the best one tried (t = 1/32, among 1 ... 1/128) wins; without damping
    t = 1. Mutations (faults in its source): the Armijo test dropped, the last trial kept
    instead of the best, the floor at 1/64 raised."""
    import inspect
    import textwrap

    from vi_core import ssn

    step = ssn.damped_step
    if fault is not None:
        src = textwrap.dedent(inspect.getsource(ssn.damped_step))
        old, new = DAMPING_FAULTS[fault]
        assert old in src
        space: dict = {}
        exec(src.replace(old, new), vars(ssn) | {}, space)
        step = space["damped_step"]

    def residual(u, lam):  # smallest at t = 0.2 on the segment from 0 to 1
        return abs(u[0] - 0.2) + 0.1 + abs(lam[0])

    def late(u, lam):  # smallest at t = 0.03: the best trial is t = 1/32
        return abs(u[0] - 0.03) + 0.1 + abs(lam[0])

    z, one = np.zeros(1), np.ones(1)
    u, lam, t, res = step(residual, z, z, one, z, 0.3, True)
    got = [(t, float(round(res, 12)), float(u[0]), float(lam[0]))]
    got.append(step(late, z, z, one, z, 0.05, True)[2])  # no trial meets Armijo
    got.append(step(residual, z, z, one, z, 0.3, False)[2])
    assert (got == [(0.25, 0.15, 0.25, 0.0), 1 / 32, 1.0]) == (fault is None), got


def test_newton_steps_count_damped_steps_and_test_the_last_residual():
    """`ssn.NewtonSteps`, the bookkeeping of the serial and PETSc loops: a full step (t = 1)
    is not counted as damped, a shorter one is; converged reads the last residual only
    (against tol, inclusive), the history keeps the starting residual first."""
    from vi_core.ssn import NewtonSteps

    steps = NewtonSteps(1e-3, [1.0])
    assert not steps.converged
    steps.record(1.0, 0.1)
    steps.record(0.5, 1e-3)
    assert (steps.damped, steps.converged, steps.history) == (1, True, [1.0, 0.1, 1e-3])
    steps.record(0.25, 2e-3)
    assert (steps.damped, steps.converged) == (2, False)
