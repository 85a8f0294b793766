"""vi_core.fgmres against an independent computation: after k iterations with a fixed linear
preconditioner M, GMRES's iterate is x0 + M c with c minimising ‖r0 − K M c‖ over the Krylov
space span{r0, (KM) r0, …, (KM)^{k−1} r0} (a least-squares problem solved here by numpy)."""

import numpy as np
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from vi_core.fgmres import fgmres_cycle


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
        x, est = fgmres_cycle(K, b, x0, solver_M(P), 0.0, k)
        true = float(np.linalg.norm(b - K @ x))
        best = _minimal_residual(K, b, x0, P, k)
        if abs(true - best) > 1e-8 * np.linalg.norm(b):
            faults.append(f"k={k}: residual {true:.3e}, minimal {best:.3e}")
        if abs(est - true) > 1e-8 * np.linalg.norm(b):
            faults.append(f"k={k}: estimate {est:.3e}, true {true:.3e}")
    return faults


@given(st.integers(0, 2**32 - 1))
def test_fgmres_iterate_is_the_minimal_residual_one(seed):
    assert _check(seed, lambda P: lambda v: P @ v) == []


def test_fgmres_check_catches_a_wrong_iterate():
    """Mutation: a preconditioner other than the one the check assumes (a transposed P)
    changes the iterates, and the check says so."""
    assert _check(0, lambda P: lambda v: P @ v) == []
    assert _check(0, lambda P: lambda v: P.T @ v) != []


@given(st.integers(0, 2**32 - 1))
def test_fgmres_stops_at_the_target(seed):
    """Exact preconditioner: one iteration; a target: the true residual is below it, with
    the iterations counted by the callback."""
    K, b, x0, _ = _system(seed)
    Kd = K.toarray()
    x, est = fgmres_cycle(K, b, x0, lambda v: np.linalg.solve(Kd, v), 0.0, 1)
    assert np.linalg.norm(b - K @ x) <= 1e-10 * np.linalg.norm(b)
    its = []
    target = 1e-6 * np.linalg.norm(b)
    x, est = fgmres_cycle(K, b, x0, lambda v: v, target, K.shape[0], its.append)
    assert np.linalg.norm(b - K @ x) <= 1.01 * target
    assert 1 < len(its) <= K.shape[0] and its[-1] == est <= target


def test_fgmres_without_progress_returns_the_start():
    """A preconditioner returning 0 (K M v = 0): no division by zero, x0 and its residual."""
    K, b, x0, _ = _system(1)
    x, est = fgmres_cycle(K, b, x0, np.zeros_like, 0.0, 5)
    assert np.array_equal(x, x0) and est == np.linalg.norm(b - K @ x0)
