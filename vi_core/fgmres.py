"""One restart cycle of right-preconditioned flexible GMRES whose memory follows its iterations.

Why not pyamg's fgmres: it allocates its Householder reflectors and preconditioned vectors for
the whole restart length up front, 2 · restart · n floats (restart 50: 800 bytes per unknown),
whatever the iterations a solve takes — at the paper scene's level 5 (386k unknowns) the
largest allocation after the multigrid set-up, for 19 iterations. Here the Arnoldi vectors
V and the preconditioned vectors Z are kept in lists, 2 · (k + 1) · n floats after k
iterations; modified Gram–Schmidt and Givens rotations (Saad, Iterative Methods for Sparse
Linear Systems, 2nd ed., Alg. 9.6), and the iterate minimises ‖b − K x‖ over x0 + span Z.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp


def fgmres_cycle(
    K: sp.spmatrix,
    b: np.ndarray,
    x0: np.ndarray,
    M: Callable[[np.ndarray], np.ndarray],
    target: float,
    restart: int,
    callback: Callable[[float], None] | None = None,
) -> tuple[np.ndarray, float]:
    """At most `restart` iterations from x0 (n,), stopping once the least-squares residual
    estimate is ≤ target (absolute); returns (x, estimate). callback(estimate) after each
    iteration. The true residual ‖b − K x‖ equals the estimate up to rounding."""
    r = b - K @ x0  # (n,)
    beta = float(np.linalg.norm(r))
    if beta <= target or restart < 1:
        return x0.copy(), beta
    V = [r / beta]  # (n,) each: orthonormal basis of the Krylov space of K M
    Z: list[np.ndarray] = []  # (n,) each: z_j = M v_j
    H = np.zeros((restart + 1, restart))  # Hessenberg matrix, rotated to upper triangular
    cs, sn = np.zeros(restart), np.zeros(restart)
    g = np.zeros(restart + 1)  # rotated right-hand side β e_1
    g[0] = beta
    k = 0
    for j in range(restart):
        z = M(V[j])
        Z.append(z)
        w = K @ z  # (n,)
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
            Z.pop()
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
    if k == 0:
        return x0.copy(), beta
    y = sla.solve_triangular(H[:k, :k], g[:k])  # (k,)
    x = x0.copy()
    for yi, zi in zip(y, Z, strict=True):
        x += yi * zi
    return x, float(abs(g[k]))
