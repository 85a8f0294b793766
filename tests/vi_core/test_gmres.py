"""vi_core.gmres against an independent computation: after k iterations with a fixed linear
preconditioner M, GMRES's iterate is x0 + M c with c minimising ‖r0 − K M c‖ over the Krylov
space span{r0, (KM) r0, …, (KM)^{k−1} r0} (a least-squares problem solved here by numpy)."""

import numpy as np
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from vi_core.gmres import gmres_cycle


def _system(seed: int):
    """A sparse non-symmetric K (n, n), b, x0 and a fixed preconditioner matrix P ≈ K⁻¹."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(20, 60))
    K = sp.random(n, n, density=0.1, random_state=rng) + sp.diags(rng.uniform(2.0, 4.0, n))
    K = sp.csr_matrix(K)
    P = np.diag(1.0 / K.diagonal()) + 0.01 * rng.standard_normal((n, n))
    return K, rng.standard_normal(n), rng.standard_normal(n), P


def _minimal_residual(K, b, x0, P, k: int) -> float:
    """min ‖r0 − K P c‖ over c in the k-dimensional Krylov space of K P (QR basis)."""
    r0 = b - K @ x0
    KP = K @ P
    cols = [r0 / np.linalg.norm(r0)]
    for _ in range(k - 1):
        cols.append(KP @ cols[-1])
        cols[-1] /= np.linalg.norm(cols[-1])
    Q = np.linalg.qr(np.column_stack(cols))[0]
    c = np.linalg.lstsq(KP @ Q, r0, rcond=None)[0]
    return float(np.linalg.norm(r0 - KP @ (Q @ c)))


def _check(seed: int, solver_M) -> list[str]:
    """Faults found: iterate not the minimal residual one, estimate not the true residual."""
    K, b, x0, P = _system(seed)
    faults = []
    for k in (1, 3, 6):
        x, est = gmres_cycle(K, b, x0, solver_M(P), 0.0, k)
        true = float(np.linalg.norm(b - K @ x))
        best = _minimal_residual(K, b, x0, P, k)
        if abs(true - best) > 1e-8 * np.linalg.norm(b):
            faults.append(f"k={k}: residual {true:.3e}, minimal {best:.3e}")
        if abs(est - true) > 1e-8 * np.linalg.norm(b):
            faults.append(f"k={k}: estimate {est:.3e}, true {true:.3e}")
    return faults


@given(st.integers(0, 2**32 - 1))
def test_gmres_iterate_is_the_minimal_residual_one(seed):
    assert _check(seed, lambda P: lambda v: P @ v) == []


def test_gmres_check_catches_a_wrong_iterate():
    """Mutation: a preconditioner other than the one the check assumes (a transposed P)
    changes the iterates, and the check says so."""
    assert _check(0, lambda P: lambda v: P @ v) == []
    assert _check(0, lambda P: lambda v: P.T @ v) != []


@given(st.integers(0, 2**32 - 1))
def test_gmres_stops_at_the_target(seed):
    """Exact preconditioner: one iteration; a target: the true residual is below it, with
    the iterations counted by the callback."""
    K, b, x0, _ = _system(seed)
    Kd = K.toarray()
    x, est = gmres_cycle(K, b, x0, lambda v: np.linalg.solve(Kd, v), 0.0, 1)
    assert np.linalg.norm(b - K @ x) <= 1e-10 * np.linalg.norm(b)
    its = []
    target = 1e-6 * np.linalg.norm(b)
    x, est = gmres_cycle(K, b, x0, lambda v: v, target, K.shape[0], its.append)
    assert np.linalg.norm(b - K @ x) <= 1.01 * target
    assert 1 < len(its) <= K.shape[0] and its[-1] == est <= target


def test_gmres_without_progress_returns_the_start():
    """A preconditioner returning 0 (K M v = 0): no division by zero, x0 and its residual."""
    K, b, x0, _ = _system(1)
    x, est = gmres_cycle(K, b, x0, np.zeros_like, 0.0, 5)
    assert np.array_equal(x, x0) and est == np.linalg.norm(b - K @ x0)


def _peak_vectors(keep_preconditioned: bool) -> float:
    """Peak memory of a 12-iteration cycle in units of one vector (n floats), by tracemalloc
    (numpy reports its buffers to it). keep_preconditioned: M stores every vector it returns,
    as flexible GMRES's list Z would (the mutation of the memory check)."""
    import tracemalloc

    n, k = 100_000, 12
    rng = np.random.default_rng(3)
    K = sp.diags(rng.uniform(1.0, 100.0, n)).tocsr()  # k iterations do not converge exactly
    b = rng.standard_normal(n)
    kept = []

    def M(v):
        z = 0.5 * v
        if keep_preconditioned:
            kept.append(z)
        return z

    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    x, _ = gmres_cycle(K, b, np.zeros(n), M, 0.0, k)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    assert np.linalg.norm(b - K @ x) < np.linalg.norm(b)
    return peak / (8 * n)


def test_gmres_holds_one_vector_per_iteration():
    """The cycle's memory is the Arnoldi vectors (k + 1 after k iterations) and a few work
    vectors, not two vectors per iteration. Mutation: a preconditioner that keeps what it
    returns (the z_j of flexible GMRES) adds k vectors and fails the bound."""
    assert _peak_vectors(False) <= 12 + 6  # measured 16.0 (FGMRES before: 30.0)
    assert _peak_vectors(True) > 12 + 6  # measured 28.0
