"""Sparse factorisations: solves, transposed solves and the condition estimate."""

import gc

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import given
from hypothesis import strategies as st

from vi_core import linalg
from vi_core.linalg import Factorization, Refactorizer, condition_estimate, pardiso_available

BACKENDS = ["splu"] + (["pardiso"] if pardiso_available() else [])


def _matrix(seed, n=60):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, 0.1, random_state=rng) + sp.diags(rng.uniform(1, 3, n))
    scale = sp.diags(10.0 ** rng.uniform(-4, 4, n))  # badly scaled rows
    return sp.csr_matrix(scale @ A)


@pytest.mark.parametrize("backend", BACKENDS)
@given(st.integers(0, 2**32 - 1))
def test_solves_and_condition_estimate(backend, seed):
    A = _matrix(seed)
    F = Factorization(A, backend)
    b = np.random.default_rng(seed).standard_normal(A.shape[0])
    assert np.linalg.norm(A @ F(b) - b) <= 1e-9 * np.linalg.norm(b) * np.abs(A).max()
    x = F.solve_transposed(b)
    assert np.linalg.norm(A.T @ x - b) <= 1e-9 * np.linalg.norm(b) * np.abs(A).max()
    true = np.linalg.cond(A.toarray(), 1)
    est = condition_estimate(F)
    assert true / 3 <= est <= true * (1 + 1e-8)  # Hager–Higham never overestimates


def _same_pattern_sequence(seed, k=4, n=60):
    """k matrices with one sparsity pattern and different values (explicit zeros included)."""
    A = _matrix(seed, n)
    rng = np.random.default_rng(seed + 1)
    out = []
    for _ in range(k):
        B = A.copy()
        B.data = B.data * rng.uniform(0.5, 2.0, B.nnz)
        B.data[rng.random(B.nnz) < 0.05] = 0.0  # explicit zeros stay in the pattern
        B.setdiag(A.diagonal() * rng.uniform(1, 2, n))
        out.append(B)
    return out


@pytest.mark.parametrize("backend", BACKENDS)
def test_refactorizer_solves_every_matrix_of_a_sequence(backend):
    R = Refactorizer(backend)
    mats = _same_pattern_sequence(3)
    b = np.ones(mats[0].shape[0])
    for A in mats:
        assert A.nnz == mats[0].nnz
        x = R(A)(b)
        assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b) * np.abs(A).max()
    assert R.factorizations == len(mats)
    # SuperLU has no symbolic reuse; PARDISO analyses the common pattern once
    assert R.analyses == (1 if backend == "pardiso" else len(mats))


@pytest.mark.skipif(not pardiso_available(), reason="pypardiso not installed (extra [fast])")
def test_pardiso_reanalyses_when_the_pattern_changes_and_old_factors_go_stale():
    R = Refactorizer("pardiso")
    a, b = _matrix(1), _matrix(2)
    Fa = R(a)
    Fb = R(b)
    assert R.analyses == 2
    with pytest.raises(RuntimeError, match="replaced"):
        Fa(np.ones(a.shape[0]))
    x = Fb(np.ones(b.shape[0]))
    assert np.linalg.norm(b @ x - 1.0) <= 1e-10 * np.abs(b).max() * np.sqrt(b.shape[0])


def _grid(k: int) -> sp.csr_matrix:
    """The 5-point Laplacian of a k × k grid in its natural (row by row, banded) numbering,
    with a non-symmetric convection term (the structure of a mesh matrix)."""
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(k, k))
    D = sp.diags([-0.3, 0.3], [-1, 1], shape=(k, k))
    eye = sp.identity(k)
    return sp.csr_matrix(sp.kron(eye, T + D) + sp.kron(T, eye))


def _fill(A: sp.spmatrix, spec: str) -> float:
    lu = spla.splu(sp.csc_matrix(A), permc_spec=spec)
    return (lu.L.nnz + lu.U.nnz) / A.nnz


def _factor_fill(F: Factorization) -> float:
    return (F._lu.L.nnz + F._lu.U.nnz) / F.A.nnz


def test_superlu_ordering_fills_less_than_the_natural_order_of_a_mesh_matrix():
    A = _grid(40)
    F = Factorization(A, "splu")
    assert _factor_fill(F) < 0.5 * _fill(A, "NATURAL")
    b = np.ones(A.shape[0])
    assert np.linalg.norm(A @ F(b) - b) <= 1e-12 * np.linalg.norm(b) * abs(A).max()


def test_mutation_natural_ordering_fails_the_fill_test(monkeypatch):
    monkeypatch.setattr(linalg, "ORDERING", "NATURAL")
    A = _grid(40)
    assert not _factor_fill(Factorization(A, "splu")) < 0.5 * _fill(A, "NATURAL")


class _CountedLU:
    """A SuperLU stand-in that counts how many of its kind are alive."""

    alive = 0
    most = 0

    def __init__(self, lu):
        self.lu = lu
        _CountedLU.alive += 1
        _CountedLU.most = max(_CountedLU.most, _CountedLU.alive)

    def solve(self, b, trans="N"):
        return self.lu.solve(b, trans=trans)

    @property
    def nnz(self):
        return self.lu.nnz

    def __del__(self):
        _CountedLU.alive -= 1


def _count_factors(monkeypatch):
    real = spla.splu
    _CountedLU.alive = _CountedLU.most = 0

    def counted(A, **kw):
        gc.collect()  # only factors still referenced count
        _CountedLU.most = max(_CountedLU.most, _CountedLU.alive + 1)
        return _CountedLU(real(A, **kw))

    monkeypatch.setattr(linalg.spla, "splu", counted)


def test_a_refactorizer_never_holds_two_factors(monkeypatch):
    _count_factors(monkeypatch)
    R = Refactorizer("splu")
    mats = _same_pattern_sequence(5, k=5)
    b = np.ones(mats[0].shape[0])
    old = None
    for A in mats:
        F = R(A)
        x = F(b)
        assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b) * np.abs(A).max()
        if old is not None:  # the replaced one was freed, even though it is still referenced
            with pytest.raises(RuntimeError, match="freed or replaced"):
                old(b)
        old = F
    assert _CountedLU.most == 1
    old.free()
    gc.collect()
    assert _CountedLU.alive == 0


def test_semismooth_newton_never_holds_two_factors(monkeypatch):
    from vi_core import solve
    from vi_core.testing import manufactured_vi

    _count_factors(monkeypatch)
    vi = manufactured_vi(3, n=40, m=16, sets=["box"]).vi
    sol = solve(vi, "ssn", linear_solver="splu", tol=1e-12)
    assert sol.converged and sol.iterations >= 2
    assert _CountedLU.most == 1


def test_mutation_keeping_the_old_factor_is_caught(monkeypatch):
    _count_factors(monkeypatch)
    monkeypatch.setattr(Factorization, "free", lambda self: None)  # the old factor stays
    R = Refactorizer("splu")
    kept = [R(A) for A in _same_pattern_sequence(5, k=3)]  # noqa: F841  (as ssn's self.last)
    assert _CountedLU.most > 1


def _two_bodies(k: int, seed: int) -> sp.csr_matrix:
    """Two k × k mesh blocks (9-point grid structure, values of either sign, weak diagonals:
    partial pivoting leaves the diagonal) coupled along one edge, as two bodies in contact."""
    rng = np.random.default_rng(seed)
    T = sp.diags([1.0, 1.0, 1.0], [-1, 0, 1], shape=(k, k))
    S = sp.csr_matrix(sp.kron(T, T))  # (k², k²) the 9-point structure
    blocks = []
    for _ in range(2):
        B = S.copy()
        B.data = rng.standard_normal(B.nnz)
        blocks.append(B + sp.diags(0.1 * rng.standard_normal(k * k)))
    A = sp.lil_matrix(sp.block_diag(blocks))
    edge = np.arange(k)  # the first row of grid nodes of each body touch
    A[edge, k * k + edge] = rng.standard_normal(k)
    A[k * k + edge, edge] = rng.standard_normal(k)
    return sp.csr_matrix(A)


def _old_options_fill(A: sp.spmatrix) -> float:
    """Fill (stored factor entries / nnz(A), as `Factorization.fill`) of SuperLU with the
    options shipped before issue 34 (minimum degree on Aᵀ + A, no SymmetricMode,
    diag_pivot_thresh 1.0)."""
    lu = spla.splu(sp.csc_matrix(A).T.tocsc(), permc_spec="MMD_AT_PLUS_A")
    return lu.nnz / A.nnz


def test_superlu_options_fill_far_less_than_the_old_ones_on_a_two_body_matrix():
    A = _two_bodies(36, seed=1)
    F = Factorization(A, "splu")
    assert F.ordering == linalg.ORDERING and F.fallback == ""
    assert F.fill < 0.5 * _old_options_fill(A)
    b = np.ones(A.shape[0])
    assert np.linalg.norm(A @ F(b) - b) <= 1e-10 * np.linalg.norm(b) * abs(A).max()


def test_mutation_the_old_pivot_threshold_fails_the_two_body_fill_test(monkeypatch):
    monkeypatch.setattr(linalg, "PIVOT_THRESHOLD", 1.0)
    A = _two_bodies(36, seed=1)
    assert not Factorization(A, "splu").fill < 0.5 * _old_options_fill(A)


def _splu_options(monkeypatch) -> list[dict]:
    """Spy: the keyword arguments of every spla.splu call."""
    seen = []
    real = spla.splu

    def spy(A, **kw):
        seen.append(kw)
        return real(A, **kw)

    monkeypatch.setattr(linalg.spla, "splu", spy)
    return seen


def _check_superlu_options(monkeypatch) -> None:
    seen = _splu_options(monkeypatch)
    Factorization(_grid(10), "splu")
    assert seen == [
        {
            "permc_spec": "MMD_AT_PLUS_A",
            "diag_pivot_thresh": 0.1,
            "options": {"SymmetricMode": True},
        }
    ]


def test_superlu_runs_with_symmetric_mode_and_the_relaxed_threshold(monkeypatch):
    # SymmetricMode changes SuperLU's time, not its fill, on the Newton matrices measured
    # (docs/benchmarks.md): the options themselves are checked
    _check_superlu_options(monkeypatch)


@pytest.mark.parametrize(
    "fault", [("SUPERLU_OPTIONS", {}), ("PIVOT_THRESHOLD", 1.0), ("ORDERING", "COLAMD")]
)
def test_mutation_other_superlu_options_fail_the_options_test(monkeypatch, fault):
    monkeypatch.setattr(linalg, *fault)
    with pytest.raises(AssertionError):
        _check_superlu_options(monkeypatch)


def test_a_factorisation_over_budget_falls_back_to_the_other_ordering(monkeypatch):
    A = _grid(60)
    fill = Factorization(A, "splu").fill
    calls = []
    real = linalg.superlu

    def over_budget_first(At, ordering, budget):  # injected: the first ordering overfills
        calls.append(ordering)
        if ordering == linalg.ORDERING:
            raise MemoryError("injected over-fill")
        return real(At, ordering, budget)

    monkeypatch.setattr(linalg, "superlu", over_budget_first)
    R = Refactorizer("splu")
    F = R(A)
    assert calls == [linalg.ORDERING, linalg.FALLBACK_ORDERING]
    assert F.ordering == linalg.FALLBACK_ORDERING and "over its budget" in F.fallback
    assert len(R.fallbacks) == 1 and linalg.FALLBACK_ORDERING in R.fallbacks[0]
    assert F.fill != fill  # the other ordering's factors
    b = np.ones(A.shape[0])
    assert np.linalg.norm(A @ F(b) - b) <= 1e-10 * np.linalg.norm(b) * abs(A).max()


def test_a_real_budget_overrun_raises_factorization_too_large():
    # a budget far below the factors' size: SuperLU's own allocation fails under RLIMIT_AS
    if linalg._vm_size() is None:
        pytest.skip("no /proc/self/status: the budget is not enforced here")
    # the budget bounds the growth of the address space: factors far larger than any heap a
    # long-lived test worker has left free (~150 MB unbounded), so the first expansion fails
    A = _grid(300)
    R = Refactorizer("splu", budget=1e5)
    with pytest.raises(linalg.FactorizationTooLarge, match="over its budget"):
        R(A)
    assert len(R.fallbacks) == 1
    F = Refactorizer("splu")(A)  # the limit is lifted again afterwards
    assert F.fallback == "" and F.fill > 1.0


def test_mutation_unbounded_budget_does_not_raise():
    A = _grid(150)
    F = Refactorizer("splu", budget=None)(A)
    assert F.fallback == ""
