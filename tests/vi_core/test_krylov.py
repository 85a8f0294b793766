"""The iterative linear path (`vi_core.krylov`): agreement with the direct solver, forcing
terms, field data, and the faults it must notice (dropped coupling, broken preconditioner)."""

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import assume, given
from hypothesis import strategies as st

from vi_core import Box, Free, MixedVI, NonNegative, product, solve
from vi_core import krylov as kr

pytest.importorskip("pyamg")

seeds = st.integers(0, 2**32 - 1)


def _laplacian(k: int) -> sp.csr_matrix:
    """5-point Laplacian on a k × k grid (Dirichlet), (k², k²)."""
    T = sp.diags([-np.ones(k - 1), 2 * np.ones(k), -np.ones(k - 1)], [-1, 0, 1])
    eye = sp.identity(k)
    return (sp.kron(T, eye) + sp.kron(eye, T)).tocsr()


def coupled_grid_vi(rng: np.random.Generator, k: int, rho: float) -> MixedVI:
    """A piezo-like VI: A = [[L, ρLᵀ], [−ρL, L]] on two k × k grid fields, dual-mortar-like B on
    the first grid row of field a (private column j, coupled to the node above), random set."""
    L = _laplacian(k)
    n1 = k * k
    A = sp.bmat([[L, rho * L.T], [-rho * L, L]]).tocsr()
    m = k
    rows = np.arange(m)
    B = sp.csr_matrix(
        (
            np.concatenate([rng.uniform(0.5, 2.0, m), -rng.uniform(0.1, 1.0, m)]),
            (np.concatenate([rows, rows]), np.concatenate([rows, rows + k])),
        ),
        shape=(m, 2 * n1),
    )
    g = rng.uniform(0.0, 1.0, m)
    kind = rng.integers(0, 3)
    Lam = (
        product(Box(-g, g))
        if kind == 0
        else NonNegative(m)
        if kind == 1
        else product(Free(m // 2), Box(-g[m // 2 :], g[m // 2 :]))
    )
    fields = {"a": np.arange(n1), "b": np.arange(n1, 2 * n1)}
    return MixedVI(A, B, 10 * rng.standard_normal(2 * n1), Lam, fields=fields)


def _agree(vi: MixedVI, tol: float = 1e-10) -> tuple:
    """Solve with SuperLU and with amg; both must reach tol; return (difference, bound, amg)."""
    d = solve(vi, "ssn", tol=tol, linear_solver="splu", estimate_condition=True)
    a = solve(vi, "ssn", tol=tol, linear_solver="amg")
    assert d.converged and a.converged, (d.residual, a.residual)
    assert a.residual <= tol
    s = vi.scaling.s_u  # compare in equilibrated variables, where the condition is estimated
    diff = np.linalg.norm((a.u - d.u) / s) / np.linalg.norm(d.u / s)
    # forward error ≤ κ · residual for each, so they differ by at most 2κ·tol
    return diff, 2 * d.info["condition_estimate"] * tol, a


@given(seeds)
def test_amg_and_direct_agree_on_coupled_grids(seed):
    rng = np.random.default_rng(seed)
    vi = coupled_grid_vi(rng, int(rng.integers(8, 20)), float(rng.uniform(0.0, 2.0)))
    diff, bound, a = _agree(vi)
    assert diff <= bound
    assert a.info["linear_solver"] == "amg" and len(a.info["krylov_iterations"]) == a.iterations


def test_amg_reports_and_is_honest_about_the_residual():
    """The reported residual is the natural residual of the returned iterate."""
    vi = coupled_grid_vi(np.random.default_rng(3), 16, 1.0)
    a = solve(vi, "ssn", tol=1e-8, linear_solver="amg")
    assert a.converged
    assert a.residual == pytest.approx(vi.residual(a.u, a.lam).relative, rel=1e-6)
    assert a.info["fallback"] == []
    assert set(a.info["threads"]) >= {"OMP_NUM_THREADS", "MKL_NUM_THREADS", "cpu_count"}
    assert a.info["amg_fields"]["a"]["near_null_dim"] == 1


def test_unknown_linear_solver_is_refused():
    vi = coupled_grid_vi(np.random.default_rng(0), 6, 0.5)
    with pytest.raises(ValueError, match="amg"):
        solve(vi, "ssn", linear_solver="cg")


def test_not_condensable_falls_back_to_direct():
    """A dense random B has no private block: amg says so and solves directly."""
    rng = np.random.default_rng(1)
    n, m = 20, 5
    A = sp.csr_matrix(np.eye(n) * 3 + 0.1 * rng.standard_normal((n, n)))
    vi = MixedVI(A, rng.standard_normal((m, n)), rng.standard_normal(n), Box(-1.0, 1.0, size=m))
    a = solve(vi, "ssn", linear_solver="amg")
    assert a.converged and a.info["fallback"][0]["reason"].startswith("not condensable")


def test_stagnation_falls_back_to_the_direct_solver(monkeypatch):
    """A preconditioner that returns nothing on R: GMRES stalls, the step is redone directly,
    the fallback is reported, and the answer is still the direct one."""
    vi = coupled_grid_vi(np.random.default_rng(5), 14, 1.0)
    monkeypatch.setattr(kr.BlockAMG, "__call__", lambda self, r: np.zeros_like(r))
    diff, bound, a = _agree(vi)
    assert a.info["fallback"] and "stagnation" in a.info["fallback"][0]["reason"]
    assert diff <= bound


def test_block_preconditioner_applies_the_coupling():
    """Blocks small enough for one level (a direct coarse solve) make BlockAMG the exact inverse
    of a block lower-triangular K = [[K_a, 0], [−G, K_b]]: the coupling block must be applied
    (mutation: couple=False leaves a residual of the size of G)."""
    k = 12
    L = _laplacian(k)
    K = sp.bmat([[L, None], [-5.0 * L, 2 * L]]).tocsr()
    n1 = k * k
    fields = [("a", np.arange(2 * n1) < n1, None), ("b", np.arange(2 * n1) >= n1, None)]
    b = np.random.default_rng(0).standard_normal(2 * n1)
    rel = {}
    for couple in (True, False):
        M = kr.BlockAMG(K, fields, couple=couple)
        assert all(len(blk.ml.levels) == 1 for blk in M.blocks)
        rel[couple] = np.linalg.norm(K @ M(b) - b) / np.linalg.norm(b)
    assert rel[True] < 1e-12 and rel[False] > 0.1, rel


def test_forcing_term():
    assert kr.forcing_term(1.0, None, 1e-10) == kr.ETA_MAX
    # fast convergence: η follows 0.9 (F_k / F_{k−1})²
    assert kr.forcing_term(1e-4, 1e-1, 1e-16) == pytest.approx(0.9e-6)
    # never more accurate than reaching tol needs
    assert kr.forcing_term(1e-6, 1e-3, 1e-10) == pytest.approx(0.1 * 1e-10 / 1e-6)
    # slow convergence: capped
    assert kr.forcing_term(0.5, 1.0, 1e-10) == kr.ETA_MAX
    # a warm start: every step solved to the floor of tol, also below a cap
    assert kr.ETA_MAX_WARM == 0.0
    assert kr.forcing_term(0.5, 1.0, 1e-10, kr.ETA_MAX_WARM) == pytest.approx(0.1 * 1e-10 / 0.5)
    assert kr.forcing_term(1e-6, 1e-3, 1e-10, 1e-8) == pytest.approx(0.1 * 1e-10 / 1e-6)


def test_field_data_is_checked_and_equilibrated():
    rng = np.random.default_rng(2)
    k = 6
    L = _laplacian(k) * rng.uniform(1, 100)  # a unit change: scales differ from 1
    A = sp.block_diag([L, 50.0 * L]).tocsr()
    n1 = k * k
    N = rng.standard_normal((n1, 2))
    fields = {"a": np.arange(n1), "b": np.arange(n1, 2 * n1)}
    vi = MixedVI(A, sp.csr_matrix((0, 2 * n1)), np.ones(2 * n1), product(), fields=fields)
    vi = MixedVI(vi.A, vi.B, vi.f, vi.Lambda, fields=fields, near_null={"a": N})
    e = vi.equilibrated
    s = vi.scaling.s_u
    # A'N' = Su A N: the equilibrated near-null vectors are Su⁻¹ N
    a = fields["a"]
    lhs = e.A[a][:, a] @ e.near_null["a"]
    assert np.allclose(lhs, s[a][:, None] * (A[a][:, a] @ N), rtol=1e-12, atol=0)
    # the mutation: unscaled vectors would not satisfy it
    assert not np.allclose(e.A[a][:, a] @ N, s[a][:, None] * (A[a][:, a] @ N), rtol=1e-6)
    with pytest.raises(ValueError, match="overlaps"):
        MixedVI(A, vi.B, vi.f, product(), fields={"a": [0, 1], "b": [1, 2]})
    with pytest.raises(ValueError, match=r"near_null\['a'\]"):
        MixedVI(A, vi.B, vi.f, product(), fields=fields, near_null={"a": N[:-1]})
    with pytest.raises(ValueError, match="needs fields"):
        MixedVI(A, vi.B, vi.f, product(), near_null={"a": N})


def _lower_vi(rng: np.random.Generator, k: int) -> MixedVI:
    """Two k × k grid fields, A = [[L, 0], [−ρL, 2L]] block lower triangular with symmetric
    diagonal blocks (so hierarchies of one level, a direct coarse solve, are exact inverses);
    B: on the first grid row of field a, a private column (weight in 0.5 … 2) and a coupling to
    two nodes of the next row (the master side)."""
    L = _laplacian(k)
    n1 = k * k
    A = sp.bmat([[L, None], [-rng.uniform(0.1, 3.0) * L, 2 * L]]).tocsr()
    rows = np.arange(k)
    cols = np.concatenate([rows, rows + k, (rows + 1) % k + k])
    vals = np.concatenate([rng.uniform(0.5, 2.0, k), -rng.uniform(0.1, 1.0, 2 * k)])
    B = sp.csr_matrix((vals, (np.tile(rows, 3), cols)), shape=(k, 2 * n1))
    fields = {"a": np.arange(n1), "b": np.arange(n1, 2 * n1)}
    return MixedVI(A, B, np.ones(2 * n1), Box(-1.0, 1.0, size=k), fields=fields)


def _newton_matrix(vi: MixedVI, cond, tied: np.ndarray, J=None, W=None) -> sp.csr_matrix:
    """The condensed Newton matrix for J (default diag(tied)), W (default I − J), written out
    from its definition (rows R: A_R − B_Rᵀ D^{-T} A_S; rows S: Dᵀ(W D^{-T} A_S + J B))."""
    A, B = vi.A.tocsr(), vi.B.tocsr()
    J = sp.diags(tied.astype(float)) if J is None else J
    W = sp.identity(vi.m) - J if W is None else W
    A_S = A[cond.S]
    K = sp.lil_matrix((vi.n, vi.n))
    K[cond.R] = A[cond.R] - B[:, cond.R].T @ (cond.Dt_inv @ A_S)
    K[cond.S] = cond.D.T @ (W @ (cond.Dt_inv @ A_S) + J @ B)
    return K.tocsr()


@given(seeds)
def test_condensed_newton_operator_is_the_newton_matrix(seed):
    """The iterative path's K, applied without being stored, and assembled for a fallback, is
    the condensed Newton matrix of its definition. Mutations: the R rows' correction with the
    wrong sign, or the S rows left as A's, are not."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    vi = coupled_grid_vi(rng, int(rng.integers(5, 12)), float(rng.uniform(0.0, 2.0)))
    cond = Condensation.detect(vi.B)
    tied = rng.uniform(size=vi.m) < 0.5
    A, B = vi.A.tocsr(), vi.B.tocsr()

    def K_S(t):  # (m, n) the S rows for the tied rows t
        J = sp.diags(t.astype(float))
        return (cond.D.T @ ((sp.identity(vi.m) - J) @ (cond.Dt_inv @ A[cond.S]) + J @ B)).tocsr()

    BR_t = sp.csr_matrix(B[:, cond.R].T)
    K = _newton_matrix(vi, cond, tied)
    x = rng.standard_normal(vi.n)
    scale = np.linalg.norm(K @ x)

    def defect(op):
        return max(
            np.linalg.norm(op @ x - K @ x) / scale,
            np.linalg.norm(op.tocsr() @ x - K @ x) / scale,
        )

    assert defect(kr.CondensedNewton(A, cond.R, cond.S, BR_t, cond.Dt_inv, K_S(tied))) < 1e-12
    assert defect(kr.CondensedNewton(A, cond.R, cond.S, -BR_t, cond.Dt_inv, K_S(tied))) > 1e-6
    assert defect(kr.CondensedNewton(A, cond.R, cond.S, BR_t, cond.Dt_inv, K_S(~tied))) > 1e-6


@given(seeds)
def test_preconditioner_is_exact_with_exact_hierarchies(seed):
    """With one-level hierarchies (exact) and 0/1 rows of J, the preconditioner is K⁻¹ for
    every set of tied rows: the tied rows are eliminated exactly and Â = T0ᵀ A T0 is the rest.
    Mutations: the wrong tied rows, or no particular solution of the tied rows, are not."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    vi = _lower_vi(rng, int(rng.integers(5, 12)))
    cond = Condensation.detect(vi.B)
    tied = rng.uniform(size=vi.m) < rng.uniform(0, 1)
    K = _newton_matrix(vi, cond, tied)
    r = rng.standard_normal(vi.n)

    def defect(tied_used, lift=None):
        ks = kr.KrylovSolver(vi.A.tocsr(), vi.B, cond, vi.fields, None)
        if lift is not None:
            ks._lift = lift
        x = ks.preconditioner(tied_used)(r)
        assert all(len(b.ml.levels) == 1 for b in ks.amg.blocks)
        return np.linalg.norm(K @ x - r) / np.linalg.norm(r)

    assert defect(tied) < 1e-10
    flipped = tied.copy()
    flipped[rng.integers(vi.m)] ^= True
    assert defect(flipped) > 1e-6
    if tied.any():
        assert defect(tied, lift=lambda q, t: np.zeros(vi.n)) > 1e-6


def _disc_jacobian(rng: np.random.Generator, m: int) -> tuple[np.ndarray, sp.csr_matrix]:
    """Rows in pairs (a friction disc per node, `Ball(g, 2)`), each disc sticking (J = I: both
    rows tied), slipping (J = γ(I − ŷŷᵀ), γ in 0.05 … 0.95: fractional rows) or a free pair
    (J = 0), as `Ball.jacobian` gives them; (tied (m,), J (m, m))."""
    kind = rng.integers(0, 3, m // 2)  # (m/2,) 0 stick, 1 slip, 2 free
    blocks = []
    for c in kind:
        if c == 0:
            blocks.append(np.eye(2))
        elif c == 1:
            a = rng.uniform(0, 2 * np.pi)
            yh = np.array([np.cos(a), np.sin(a)])
            blocks.append(rng.uniform(0.05, 0.95) * (np.eye(2) - np.outer(yh, yh)))
        else:
            blocks.append(np.zeros((2, 2)))
    return np.repeat(kind == 0, 2), sp.block_diag(blocks, format="csr")


@given(seeds)
def test_preconditioner_is_exact_with_slip_discs(seed):
    """3D slip discs: fractional rows of J are free rows with a spring M = W_FF^{-1} J_FF, and
    with one-level hierarchies the preconditioner is K⁻¹ again. Mutation: the slip rows counted
    as J = 0 (the previous approximation) is not."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    vi = _lower_vi(rng, 2 * int(rng.integers(3, 6)))  # an even number of rows: discs
    cond = Condensation.detect(vi.B)
    tied, J = _disc_jacobian(rng, vi.m)
    W = sp.identity(vi.m, format="csr") - J
    K = _newton_matrix(vi, cond, tied, J)
    r = rng.standard_normal(vi.n)

    def defect(spring):
        ks = kr.KrylovSolver(vi.A.tocsr(), vi.B, cond, vi.fields, None)
        x = ks.preconditioner(tied, spring)(r)
        assert all(len(b.ml.levels) == 1 for b in ks.amg.blocks)
        return np.linalg.norm(K @ x - r) / np.linalg.norm(r)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(kr, "SPRING_CAP", np.inf)  # uncapped: the exact springs
        spring = kr.Spring.of(tied, W, J)
    assert defect(spring) < 1e-10
    if spring is not None:  # some disc slips
        assert defect(None) > 1e-6


@given(seeds)
def test_preconditioner_is_exact_with_slip_rows_coupled_to_tied_rows(seed):
    """J_FT ≠ 0 (a slip row depending on a tied row, as Coulomb's on its node's normal row)
    with W_FT = 0: the springs' right-hand side W_FF^{-1}(q_F − J_FT q_T) keeps the
    preconditioner exact. Mutations: that coupling's sign flipped, or dropped, are not."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    vi = _lower_vi(rng, 2 * int(rng.integers(3, 6)))
    cond = Condensation.detect(vi.B)
    tied, J = _disc_jacobian(rng, vi.m)
    slip = ~tied & (np.diff(J.indptr) > 0)  # (m,) the fractional rows
    assume(slip.any() and tied.any())
    W = sp.identity(vi.m, format="csr") - J  # W_FT = 0: the coupling is added to J only
    C = np.zeros((vi.m, vi.m))
    C[np.ix_(slip, tied)] = rng.uniform(-1.0, 1.0, (slip.sum(), tied.sum()))
    J = (J + sp.csr_matrix(C)).tocsr()
    K = _newton_matrix(vi, cond, tied, J, W)
    r = rng.standard_normal(vi.n)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(kr, "SPRING_CAP", np.inf)  # uncapped: the exact springs
        spring = kr.Spring.of(tied, W, J)

    def defect(J_FT):
        ks = kr.KrylovSolver(vi.A.tocsr(), vi.B, cond, vi.fields, None)
        x = ks.preconditioner(tied, dataclasses.replace(spring, J_FT=J_FT))(r)
        return np.linalg.norm(K @ x - r) / np.linalg.norm(r)

    assert spring.J_FT.nnz > 0
    assert defect(spring.J_FT) < 1e-10
    assert defect(-spring.J_FT) > 1e-6
    assert defect(0 * spring.J_FT) > 1e-6


def _t0(ks: kr.KrylovSolver, tied: np.ndarray) -> sp.csr_matrix:
    """T0 (n, n_R + n_F) written out from its definition, column by column: y = (u_R, s_F) ↦ u
    with u_R = y_R, u_S = D^{-1}(C E_F s_F − E_T (B_R u_R)_T) (module docstring)."""
    n_R, F = ks.R.size, np.flatnonzero(~tied)
    D_inv = np.linalg.inv(ks.D.toarray())
    T0 = np.zeros((ks.n, n_R + F.size))
    for j in range(n_R + F.size):
        y = np.zeros(n_R + F.size)
        y[j] = 1.0
        z = np.zeros(tied.size)  # D u_S
        z[F] = ks.scale[F] * y[n_R:]
        z[tied] = -(ks.B_R @ y[:n_R])[tied]
        T0[ks.R, j] = y[:n_R]
        T0[ks.S, j] = D_inv @ z
    return sp.csr_matrix(T0)


@given(seeds)
def test_field_blocks_are_those_of_t0t_a_t0(seed):
    """The field blocks of Â gathered from A's R × R block and the low-rank corrections
    (`_blocks`) are those of T0ᵀ (A + B_Fᵀ M B_F) T0 formed from T0 written out, with and
    without springs, for A with non-symmetric coupling: the symmetric part of each diagonal
    block and the coupling block. Mutation: any one correction term dropped is not."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    vi = _lower_vi(rng, 2 * int(rng.integers(3, 6)))
    cond = Condensation.detect(vi.B)
    tied, J = _disc_jacobian(rng, vi.m)
    spring = kr.Spring.of(tied, sp.identity(vi.m, format="csr") - J, J)
    ks = kr.KrylovSolver(vi.A.tocsr(), vi.B, cond, vi.fields, None)
    T0 = _t0(ks, tied)
    A = vi.A.tocsr()
    if spring is not None:
        B_F = vi.B.tocsr()[np.flatnonzero(~tied)]
        A = A + B_F.T @ spring.M @ B_F
    ref = (T0.T @ A @ T0).toarray()  # (n_y, n_y)
    scale = np.abs(ref).max()

    def defect():
        blocks = ks._blocks(tied, spring)
        assert [b["name"] for b in blocks] == ["a", "b"] and blocks[0]["lower"] == []
        a, b = (blk["index"] for blk in blocks)
        worst = max(
            np.abs(blk["sym"].toarray() - (ref[np.ix_(i, i)] + ref[np.ix_(i, i)].T) / 2).max()
            for blk, i in zip(blocks, (a, b), strict=True)
        )
        [(j, C)] = blocks[1]["lower"]
        return max(worst, np.abs(C.toarray() - ref[np.ix_(b, a)]).max()) / scale

    assert defect() < 1e-12
    terms = ks._corrections(tied, spring)
    assert len(terms) == 3 + (spring is not None)
    for i, term in enumerate(terms):
        if abs(term).max() == 0:
            continue
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(
                ks, "_corrections", lambda *a, i=i: [t for j, t in enumerate(terms) if j != i]
            )
            assert defect() > 1e-6


def _block(A: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(k_r, k_c) dense A[rows][:, cols], rows/columns −1 zero."""
    out = np.zeros((rows.size, cols.size))
    out[np.ix_(rows >= 0, cols >= 0)] = A[rows[rows >= 0]][:, cols[cols >= 0]].toarray()
    return out


@given(seeds)
def test_restricted_plus_is_the_block_plus_the_corrections(seed):
    """`restricted_plus` (A's rows and columns gathered in chunks from its index arrays, a few
    rows replaced by their sum with Z) is A[rows][:, cols] + Z, with rows/columns −1 zero and
    explicit zeros in A, over chunks of a few entries; given A's lone entries its pattern is
    symmetric, also where A's lacks one transpose. Mutations: Z's rows put in place of A's
    rows instead of added to them, or Zᵀ's pattern and A's lone entries left out, are not."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 40))
    A = sp.random(n, n, density=0.3, format="csr", random_state=rng)
    A.data[rng.uniform(size=A.nnz) < 0.1] = 0.0  # explicit zeros

    def some():  # (k,) an increasing subset of A's rows, then a few −1
        sub = np.flatnonzero(rng.uniform(size=n) < 0.7)
        return np.concatenate([sub, -np.ones(int(rng.integers(0, 5)), dtype=int)])

    rows, cols = some(), some()
    Z = sp.random(rows.size, cols.size, density=0.3, format="csr", random_state=rng)
    Z = sp.diags((rng.uniform(size=rows.size) < 0.3).astype(float)) @ Z  # a few rows
    ref = _block(A, rows, cols) + Z.toarray()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(kr, "CHUNK", int(rng.integers(1, 8)))
        out = kr.restricted_plus(A, rows, cols, Z)
    assert out.has_sorted_indices
    assert np.array_equal(out.toarray(), ref)
    row_of = np.full(n, -1)
    row_of[rows[rows >= 0]] = np.flatnonzero(rows >= 0)
    col_of = np.full(n, -1)
    col_of[cols[cols >= 0]] = np.flatnonzero(cols >= 0)
    stored = np.diff(Z.indptr) > 0  # (k_r,) Z's rows
    row_of[rows[stored & (rows >= 0)]] = -1
    replaced = kr.gather_rows(A, row_of, col_of, Z.shape, extra=Z)
    if (stored & (np.abs(ref - Z.toarray()).sum(axis=1) > 0)).any():  # A's row there not zero
        assert not np.array_equal(replaced.toarray(), ref)
    # symmetric: the pattern of A's pattern (symmetric but for one entry) plus a square Z is
    S = (A + A.T).tocsr()
    i, j = S.nonzero()
    if (i != j).any():  # one entry (i, j) dropped, (j, i) kept
        k = np.flatnonzero(i != j)[0]
        S[i[k], j[k]] = 0.0
        S.eliminate_zeros()
    Z = sp.random(rows.size, rows.size, density=0.3, format="csr", random_state=rng)
    Z = sp.diags((rng.uniform(size=rows.size) < 0.3).astype(float)) @ Z

    def pattern(symmetric):  # (k_r, k_r) 0/1 and whether the values are right
        out = kr.restricted_plus(S, rows, rows, Z, kr.lone_entries(S) if symmetric else None)
        ok = np.array_equal(out.toarray(), _block(S, rows, rows) + Z.toarray())
        out.data[:] = 1.0
        return out.toarray(), ok

    P, ok = pattern(True)
    assert ok and np.array_equal(P, P.T)
    P, ok = pattern(False)
    ones = sp.csr_matrix((np.ones(S.nnz), S.indices, S.indptr), shape=S.shape)
    Q = (_block(ones, rows, rows) + abs(Z).toarray()) > 0  # (k_r, k_r) the two patterns
    assert ok and np.array_equal(P > 0, Q)
    if not np.array_equal(Q, Q.T):  # without Zᵀ's pattern the result's is not symmetric
        assert not np.array_equal(P, P.T)


@given(seeds)
def test_symmetric_part(seed):
    """`symmetric_part` is (K + Kᵀ)/2 as the sum computes it, the same numbers, with its zeros
    dropped: in place for a symmetric pattern (values not symmetric, explicit zeros, entries
    with a zero symmetric part), and by the sum for a pattern that is not symmetric."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 30))
    mask = rng.uniform(size=(n, n)) < 0.3  # (n, n) the pattern
    if rng.uniform() < 0.7:
        mask |= mask.T  # symmetric
    Kd = np.where(mask, rng.standard_normal((n, n)), 0.0)  # (n, n) values not symmetric
    i, j = np.nonzero(np.triu(mask, 1))
    Kd[j[:2], i[:2]] = -Kd[i[:2], j[:2]]  # pairs with a zero symmetric part
    P = sp.csr_matrix(mask.astype(float))
    P.sort_indices()
    data = Kd[np.repeat(np.arange(n), np.diff(P.indptr)), P.indices]  # (nnz,)
    data[rng.uniform(size=data.size) < 0.1] = 0.0  # explicit zeros
    K = sp.csr_matrix((data, P.indices, P.indptr), shape=(n, n))
    K.sort_indices()
    ref = (K + K.T).tocsr()
    ref.data *= 0.5
    ref.eliminate_zeros()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(kr, "CHUNK", int(rng.integers(1, 8)))
        out = kr.symmetric_part(K.copy())
    out.sort_indices()
    assert np.array_equal(out.indptr, ref.indptr) and np.array_equal(out.indices, ref.indices)
    assert np.array_equal(out.data, ref.data)


def test_springs_are_capped():
    """A disc that has only just started to slip (γ = 1: W_FF singular) gets the spring
    SPRING_CAP, one with γ = 0.5 (κ = 1) κ/(1 + κ/SPRING_CAP); the free row along ŷ none."""
    yh = np.array([0.6, 0.8])
    P = np.eye(2) - np.outer(yh, yh)  # the projection across ŷ
    J = sp.csr_matrix(sp.block_diag([P, 0.5 * P]))
    W = sp.identity(4, format="csr") - J
    s = kr.Spring.of(np.zeros(4, dtype=bool), W, J)
    kappa = np.linalg.eigvalsh(s.M.toarray())  # (4,) ascending
    c = kr.SPRING_CAP
    assert np.allclose(kappa, [0.0, 0.0, 1 / (1 + 1 / c), c], rtol=1e-12, atol=1e-12)
    assert s.rows.all()


def test_block_inverse():
    """Blocks of sizes 1–3 in a permuted order: W⁻¹W = I; a dropped off-diagonal entry is not
    the inverse."""
    rng = np.random.default_rng(3)
    blocks = [rng.standard_normal((s, s)) + 3 * np.eye(s) for s in rng.integers(1, 4, 40)]
    W = sp.block_diag(blocks, format="csr")
    p = rng.permutation(W.shape[0])
    W = W[p][:, p]
    eye = sp.identity(W.shape[0])
    assert abs(kr.block_inverse(W) @ W - eye).max() < 1e-12
    V = W.tolil()
    i = next(i for i in range(W.shape[0]) if W[i].nnz > 1)
    j = next(j for j in W[i].indices if j != i)
    V[i, j] = 0.0
    assert abs(kr.block_inverse(V.tocsr()) @ W - eye).max() > 1e-6


@pytest.mark.parametrize("exact", [True, False])
def test_krylov_step_solves_the_s_rows_exactly(exact, monkeypatch):
    """An inexact step (η = 1e-6) still meets the S rows to rounding, so a slip row's multiplier
    λ = D^{-T}(f_S − A_S u) is on its bound as after a direct solve (nested iteration reads the
    stick/slip partition from it; paper scene level 5: 8 Newton steps instead of 2 without).
    Mutation (exact=False): without the exact S rows after GMRES they are off by about η."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(7)
    vi = _lower_vi(rng, 40)  # 1,600 unknowns per field: hierarchies of more than one level
    cond = Condensation.detect(vi.B)
    tied = np.arange(vi.m) % 2 == 0
    K = _newton_matrix(vi, cond, tied)
    b = rng.standard_normal(vi.n)
    ks = kr.KrylovSolver(vi.A.tocsr(), vi.B, cond, vi.fields, None)
    if not exact:
        monkeypatch.setattr(kr.KrylovSolver, "_exact_S_rows", lambda self, K, b, x: None)
    x, rec = ks(K, b, None, 1e-6, 1e-10, tied)
    assert rec["fallback"] is None and len(ks.amg.blocks[0].ml.levels) > 1
    assert np.linalg.norm(K @ x - b) <= 1e-6 * np.linalg.norm(b)
    s_rows = np.linalg.norm((K @ x - b)[cond.S]) / np.linalg.norm(b)
    assert (s_rows <= 1e-13) == exact, s_rows


def test_a_few_changed_rows_keep_the_old_preconditioner(monkeypatch):
    """One row changing type keeps the hierarchy: the preconditioner stays the exact inverse
    of the Newton matrix of the old tied rows (so GMRES sees a rank-one difference only).
    Mutation (REUSE = 0: rebuild on every change): a second set-up."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(11)
    vi = _lower_vi(rng, 20)  # 20 rows: one changed is 5 %
    cond = Condensation.detect(vi.B)
    old = np.arange(vi.m) % 2 == 0
    new = old.copy()
    new[1] = True
    r = rng.standard_normal(vi.n)
    for reuse, setups in ((kr.REUSE, 1), (0.0, 2)):
        monkeypatch.setattr(kr, "REUSE", reuse)
        ks = kr.KrylovSolver(vi.A.tocsr(), vi.B, cond, vi.fields, None)
        ks.preconditioner(old)
        x = ks.preconditioner(new)(r)
        assert len(ks.setups) == setups
        K = _newton_matrix(vi, cond, old if setups == 1 else new)
        assert np.linalg.norm(K @ x - r) <= 1e-10 * np.linalg.norm(r)


@pytest.mark.parametrize("field", ["displacement", "potential"])
def test_smoothed_aggregation_is_pyamgs_hierarchy(field, monkeypatch):
    """The memory-lean hierarchy (`smoothed_aggregation`: `strength_within_parts` from A's
    structure, `energy_smoothing` on the finest level, the coarser levels' strength cut
    between the parts of their aggregates) is pyamg's smoothed_aggregation_solver with
    pyamg's strength cut between the bodies on every level, to rounding: the operators of
    every level and one W-cycle. Mutations: one CG step of the energy smoothing fewer, the
    strength not cut between the bodies on the finest level, or not on the coarser ones, are
    not."""
    import pyamg

    from problems.plugins import piezo_contact as pc
    from problems.scene import load_scene
    from vi_core.ssn import Condensation

    e = pc.build(load_scene("paper_two_body"), 3).vi.equilibrated  # 3 AMG levels
    ks = kr.KrylovSolver(e.A, e.B, Condensation.detect(e.B), e.fields, e.near_null)
    tied = np.ones(e.m, dtype=bool)  # every row tied: the bodies glued, Â couples them
    blk = next(b for b in ks._blocks(tied) if b["name"] == field)
    A, nn = blk["sym"], blk["nn"]
    part = np.concatenate([kr.bodies(e.A)[ks.R], kr.bodies(e.A)[ks.S][~tied]])[blk["index"]]

    def cut(C, part):  # pyamg's strength C with the connections between two parts dropped
        C = sp.coo_matrix(C)
        keep = part[C.row] == part[C.col]
        return sp.csr_matrix((C.data[keep], (C.row[keep], C.col[keep])), shape=C.shape), keep

    # the reference: pyamg's symmetric strength (θ = 0) cut between the bodies on the finest
    # level, then level by level between the parts of the aggregates (each aggregate's
    # members in one part), rebuilt with one more level's strength given each time
    C, keep = cut(pyamg.strength.symmetric_strength_of_connection(A, 0.0), part)
    cut_fine = field == "displacement"  # the potential lives in one body (the cradle)
    assert (~keep).any() == cut_fine
    strength, parts, cut_coarse = [("predefined", {"C": C})], [part], False
    kw = {} if nn is None else {"B": nn}
    while True:
        ref = pyamg.smoothed_aggregation_solver(
            A, max_coarse=500, coarse_solver="splu", smooth=kr.SMOOTH, keep=True,
            strength=strength + ["symmetric"] * (kr.MAX_LEVELS - len(strength)), **kw,
        )  # fmt: skip
        if len(ref.levels) - 1 == len(strength):
            break
        agg = sp.coo_matrix(ref.levels[len(strength) - 1].AggOp)
        p = np.empty(agg.shape[1], dtype=part.dtype)
        p[agg.col] = parts[-1][agg.row]
        C, keep = cut(
            pyamg.strength.symmetric_strength_of_connection(ref.levels[len(strength)].A, 0.0), p
        )
        cut_coarse |= bool((~keep).any())
        strength.append(("predefined", {"C": C}))
        parts.append(p)
    assert cut_coarse == cut_fine  # the coarser levels of the glued bodies connect them
    r = np.random.default_rng(0).standard_normal(A.shape[0])

    def cycle(ml):
        return ml.solve(r, x0=np.zeros_like(r), tol=0.0, maxiter=1, cycle="W")

    x_ref = cycle(ref)
    ml = kr.smoothed_aggregation(A, nn, part)
    assert len(ml.levels) == len(ref.levels) >= 3
    for a, b in zip(ml.levels, ref.levels, strict=True):
        assert a.A.shape == b.A.shape
        scale = abs(b.A).max()
        assert abs(sp.csr_matrix(a.A) - sp.csr_matrix(b.A)).max() <= 1e-12 * scale
    assert np.linalg.norm(cycle(ml) - x_ref) <= 1e-12 * np.linalg.norm(x_ref)
    if cut_fine:
        ml = kr.smoothed_aggregation(A, nn, None)
        assert np.linalg.norm(cycle(ml) - x_ref) > 1e-6 * np.linalg.norm(x_ref)
        with monkeypatch.context() as m:  # the coarser levels not cut
            m.setattr(kr, "coarse_parts", lambda AggOp, part: None)
            ml = kr.smoothed_aggregation(A, nn, part)
        assert np.linalg.norm(cycle(ml) - x_ref) > 1e-6 * np.linalg.norm(x_ref)
    monkeypatch.setattr(kr, "SMOOTH", ("energy", {**kr.SMOOTH[1], "maxiter": 1}))
    ml = kr.smoothed_aggregation(A, nn, part)
    assert np.linalg.norm(cycle(ml) - x_ref) > 1e-6 * np.linalg.norm(x_ref)
    monkeypatch.setattr(kr, "SMOOTH", ("energy", {**kr.SMOOTH[1], "maxiter": 1}))
    ml = kr.smoothed_aggregation(A, nn, part)
    assert np.linalg.norm(cycle(ml) - x_ref) > 1e-6 * np.linalg.norm(x_ref)


def test_auto_chooses_direct_below_and_amg_above_the_size_of_its_kind(monkeypatch):
    assert kr.auto_linear_solver(10_000, 1_000) == "auto"  # 10 per row: 2D, small
    assert kr.auto_linear_solver(kr.AUTO_AMG_NNZ[2] + 1, 100_000) == "amg"
    assert kr.auto_linear_solver(kr.AUTO_AMG_NNZ[2] + 1, 100_000, condensable=False) == "auto"
    # 3D (≥ ROW_3D entries per row) switches at its own, smaller size
    n3 = kr.AUTO_AMG_NNZ[3] // 60 + 1
    assert kr.auto_linear_solver(60 * n3, n3) == "amg"
    assert kr.auto_linear_solver(20 * n3, n3) == "auto"  # the same entries, 2D
    vi = coupled_grid_vi(np.random.default_rng(2), 12, 1.0)
    small = solve(vi, "ssn", tol=1e-8)  # auto, small: direct
    assert small.info["linear_solver"] == "splu" and small.info["linear_solver_asked"] == "auto"
    monkeypatch.setattr(kr, "AUTO_AMG_NNZ", {2: 10, 3: 10})
    import vi_core.ssn as ssn

    monkeypatch.setattr(ssn, "auto_linear_solver", kr.auto_linear_solver)
    big = solve(vi, "ssn", tol=1e-8)
    assert big.info["linear_solver"] == "amg" and big.converged


def test_a_factorisation_over_budget_restarts_the_solve_with_amg(monkeypatch):
    """Injected: every SuperLU factorisation of the fine matrix is over budget. The solve ends
    on the iterative path and says so (info and a warning); the answer is the direct one."""
    from vi_core import linalg

    vi = coupled_grid_vi(np.random.default_rng(4), 14, 1.0)
    d = solve(vi, "ssn", tol=1e-10, linear_solver="splu", estimate_condition=True)
    n = vi.n

    real = linalg.superlu

    def over(At, ordering, budget):
        if At.shape[0] == n:
            raise MemoryError("injected over-fill")
        return real(At, ordering, budget)

    monkeypatch.setattr(linalg, "superlu", over)
    a = solve(vi, "ssn", tol=1e-10, linear_solver="splu")
    assert "solved with amg" in a.info["factorisation_fallback"]
    assert a.info["linear_solver"] == "amg" and a.converged
    assert any("over budget" in w for w in a.warnings)
    s = vi.scaling.s_u
    diff = np.linalg.norm((a.u - d.u) / s) / np.linalg.norm(d.u / s)
    assert diff <= 2 * d.info["condition_estimate"] * 1e-10


def test_a_solve_that_does_not_condense_cannot_fall_back_and_raises(monkeypatch):
    from vi_core import linalg

    vi = coupled_grid_vi(np.random.default_rng(4), 14, 1.0)
    monkeypatch.setattr(linalg, "superlu", lambda At, o, b: (_ for _ in ()).throw(MemoryError()))
    with pytest.raises(linalg.FactorizationTooLarge):
        solve(vi, "ssn", linear_solver="splu", condense=False)


def test_mutation_ssn_not_catching_the_overrun_fails_the_fallback_test(monkeypatch):
    import vi_core.ssn as ssn

    class Other(Exception):
        pass

    monkeypatch.setattr(ssn, "FactorizationTooLarge", Other)  # the handler no longer matches
    with pytest.raises(MemoryError):
        test_a_factorisation_over_budget_restarts_the_solve_with_amg(monkeypatch)
