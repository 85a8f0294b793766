"""The tied-rows preconditioner (`vi_core.tied_preconditioner`): exact with exact hierarchies
(0/1 rows, slip discs, slip rows coupled to tied rows), its field blocks those of T0ᵀ A T0, the
springs capped, the hierarchy kept while few rows change."""

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import assume, given
from hypothesis import strategies as st

from vi_core import tied_preconditioner
from vi_core.tied_preconditioner import TiedPreconditioner

from .newton_systems import lower_vi, newton_matrix

pytest.importorskip("pyamg")

seeds = st.integers(0, 2**32 - 1)


@given(seeds)
def test_preconditioner_is_exact_with_exact_hierarchies(seed):
    """With one-level hierarchies (exact) and 0/1 rows of J, the preconditioner is K⁻¹ for
    every set of tied rows: the tied rows are eliminated exactly and Â = T0ᵀ A T0 is the rest.
    Mutations: the wrong tied rows, or no particular solution of the tied rows, are not."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    vi = lower_vi(rng, int(rng.integers(5, 12)))
    cond = Condensation.detect(vi.B)
    tied = rng.uniform(size=vi.m) < rng.uniform(0, 1)
    K = newton_matrix(vi, cond, tied)
    r = rng.standard_normal(vi.n)

    def defect(tied_used, lift=None):
        ks = TiedPreconditioner(vi.A.tocsr(), vi.B, cond, vi.fields, None)
        if lift is not None:
            ks._lift = lift
        x = ks(tied_used)(r)
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
    vi = lower_vi(rng, 2 * int(rng.integers(3, 6)))  # an even number of rows: discs
    cond = Condensation.detect(vi.B)
    tied, J = _disc_jacobian(rng, vi.m)
    W = sp.identity(vi.m, format="csr") - J
    K = newton_matrix(vi, cond, tied, J)
    r = rng.standard_normal(vi.n)

    def defect(spring):
        ks = TiedPreconditioner(vi.A.tocsr(), vi.B, cond, vi.fields, None)
        x = ks(tied, spring)(r)
        assert all(len(b.ml.levels) == 1 for b in ks.amg.blocks)
        return np.linalg.norm(K @ x - r) / np.linalg.norm(r)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tied_preconditioner, "SPRING_CAP", np.inf)  # uncapped: the exact springs
        spring = tied_preconditioner.Spring.of(tied, W, J)
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
    vi = lower_vi(rng, 2 * int(rng.integers(3, 6)))
    cond = Condensation.detect(vi.B)
    tied, J = _disc_jacobian(rng, vi.m)
    slip = ~tied & (np.diff(J.indptr) > 0)  # (m,) the fractional rows
    assume(slip.any() and tied.any())
    W = sp.identity(vi.m, format="csr") - J  # W_FT = 0: the coupling is added to J only
    C = np.zeros((vi.m, vi.m))
    C[np.ix_(slip, tied)] = rng.uniform(-1.0, 1.0, (slip.sum(), tied.sum()))
    J = (J + sp.csr_matrix(C)).tocsr()
    K = newton_matrix(vi, cond, tied, J, W)
    r = rng.standard_normal(vi.n)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tied_preconditioner, "SPRING_CAP", np.inf)  # uncapped: the exact springs
        spring = tied_preconditioner.Spring.of(tied, W, J)

    def defect(J_FT):
        ks = TiedPreconditioner(vi.A.tocsr(), vi.B, cond, vi.fields, None)
        x = ks(tied, dataclasses.replace(spring, J_FT=J_FT))(r)
        return np.linalg.norm(K @ x - r) / np.linalg.norm(r)

    assert spring.J_FT.nnz > 0
    assert defect(spring.J_FT) < 1e-10
    assert defect(-spring.J_FT) > 1e-6
    assert defect(0 * spring.J_FT) > 1e-6


def _t0(ks: TiedPreconditioner, tied: np.ndarray) -> sp.csr_matrix:
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
    vi = lower_vi(rng, 2 * int(rng.integers(3, 6)))
    cond = Condensation.detect(vi.B)
    tied, J = _disc_jacobian(rng, vi.m)
    spring = tied_preconditioner.Spring.of(tied, sp.identity(vi.m, format="csr") - J, J)
    ks = TiedPreconditioner(vi.A.tocsr(), vi.B, cond, vi.fields, None)
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


def test_springs_are_capped():
    """A disc that has only just started to slip (γ = 1: W_FF singular) gets the spring
    SPRING_CAP, one with γ = 0.5 (κ = 1) κ/(1 + κ/SPRING_CAP); the free row along ŷ none."""
    yh = np.array([0.6, 0.8])
    P = np.eye(2) - np.outer(yh, yh)  # the projection across ŷ
    J = sp.csr_matrix(sp.block_diag([P, 0.5 * P]))
    W = sp.identity(4, format="csr") - J
    s = tied_preconditioner.Spring.of(np.zeros(4, dtype=bool), W, J)
    kappa = np.linalg.eigvalsh(s.M.toarray())  # (4,) ascending
    c = tied_preconditioner.SPRING_CAP
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
    assert abs(tied_preconditioner.block_inverse(W) @ W - eye).max() < 1e-12
    V = W.tolil()
    i = next(i for i in range(W.shape[0]) if W[i].nnz > 1)
    j = next(j for j in W[i].indices if j != i)
    V[i, j] = 0.0
    assert abs(tied_preconditioner.block_inverse(V.tocsr()) @ W - eye).max() > 1e-6


def test_a_few_changed_rows_keep_the_old_preconditioner(monkeypatch):
    """One row changing type keeps the hierarchy: the preconditioner stays the exact inverse
    of the Newton matrix of the old tied rows (so GMRES sees a rank-one difference only).
    Mutation (REUSE = 0: rebuild on every change): a second set-up."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(11)
    vi = lower_vi(rng, 20)  # 20 rows: one changed is 5 %
    cond = Condensation.detect(vi.B)
    old = np.arange(vi.m) % 2 == 0
    new = old.copy()
    new[1] = True
    r = rng.standard_normal(vi.n)
    for reuse, setups in ((tied_preconditioner.REUSE, 1), (0.0, 2)):
        monkeypatch.setattr(tied_preconditioner, "REUSE", reuse)
        ks = TiedPreconditioner(vi.A.tocsr(), vi.B, cond, vi.fields, None)
        ks(old)
        x = ks(new)(r)
        assert len(ks.setups) == setups
        K = newton_matrix(vi, cond, old if setups == 1 else new)
        assert np.linalg.norm(K @ x - r) <= 1e-10 * np.linalg.norm(r)
