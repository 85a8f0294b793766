"""One restart cycle of right-preconditioned GMRES whose memory follows its iterations.

Why not pyamg's fgmres: it allocates its Householder reflectors and preconditioned vectors for
the whole restart length up front, 2 · restart · n floats (restart 50: 800 bytes per unknown),
whatever the iterations a solve takes — at the paper scene's level 5 (386k unknowns) the
largest allocation after the multigrid set-up, for 19 iterations. Here only the Arnoldi vectors
V are kept, in a list: (k + 1) · n floats after k iterations. The preconditioner M of the
iterative path (`tied_preconditioner.TiedPreconditioner`: multigrid cycles with fixed smoothers,
an exact coarse solve, exact tied rows) is one fixed linear map during a cycle, so the iterate
x0 + Σ y_j M v_j is x0 + M (V y): one more application of M at the end instead of keeping the
preconditioned vectors z_j = M v_j (flexible GMRES keeps them, for a preconditioner that
changes between iterations). That halves the vectors: on the 10.7M-unknown variant of the paper
scene (README, "Scale") the 27 iterations of the fine step held 2 · 28 vectors of 85 MB, 4.8 GB,
in the flexible variant used before. Modified Gram–Schmidt and Givens rotations (Saad,
Iterative Methods for Sparse Linear Systems, 2nd ed., Alg. 6.9 with right preconditioning,
§9.3.2).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp


def gmres_cycle(
    K: sp.spmatrix,
    b: np.ndarray,
    x0: np.ndarray,
    M: Callable[[np.ndarray], np.ndarray],
    target: float,
    restart: int,
    callback: Callable[[float], None] | None = None,
) -> tuple[np.ndarray, float]:
    """At most `restart` iterations from x0 (n,), stopping once the least-squares residual
    estimate is ≤ target (absolute); returns (x, estimate). M must be linear and the same map
    throughout the cycle. callback(estimate) after each iteration. The true residual
    ‖b − K x‖ equals the estimate up to rounding."""
    r = b - K @ x0  # (n,)
    beta = float(np.linalg.norm(r))
    if beta <= target or restart < 1:
        return x0.copy(), beta
    V = [r / beta]  # (n,) each: orthonormal basis of the Krylov space of K M
    del r
    H = np.zeros((restart + 1, restart))  # Hessenberg matrix, rotated to upper triangular
    cs, sn = np.zeros(restart), np.zeros(restart)
    g = np.zeros(restart + 1)  # rotated right-hand side β e_1
    g[0] = beta
    k = 0
    for j in range(restart):
        w = K @ M(V[j])  # (n,)
        for i in range(j + 1):  # modified Gram–Schmidt
            H[i, j] = V[i] @ w
            w -= H[i, j] * V[i]
        h = float(np.linalg.norm(w))
        H[j + 1, j] = h
        for i in range(j):  # the earlier rotations on the new column
            H[i, j], H[i + 1, j] = (
                cs[i] * H[i, j] + sn[i] * H[i + 1, j],
                -sn[i] * H[i, j] + cs[i] * H[i + 1, j],
            )
        d = float(np.hypot(H[j, j], H[j + 1, j]))
        if d == 0.0:  # K M v_j = 0 (a preconditioner returning 0): no progress, stop before it
            break
        cs[j], sn[j] = H[j, j] / d, H[j + 1, j] / d
        H[j, j], H[j + 1, j] = d, 0.0
        g[j + 1], g[j] = -sn[j] * g[j], cs[j] * g[j]
        k = j + 1
        if callback is not None:
            callback(abs(g[k]))
        if abs(g[k]) <= target or h == 0.0:  # converged, or the space is invariant
            break
        V.append(w / h)
    del w
    if k == 0:
        return x0.copy(), beta
    y = sla.solve_triangular(H[:k, :k], g[:k])  # (k,)
    v = np.zeros_like(V[0])  # (n,) V y, accumulated in place
    for yi, vi in zip(y, V[:k], strict=True):
        v += yi * vi
    del V
    return x0 + M(v), float(abs(g[k]))
