"""Linear systems for the tests of the iterative path (`vi_core.krylov` and its parts): grid
fields, dual-mortar-like constraints, and the condensed Newton matrix written out from its
definition."""

import numpy as np
import scipy.sparse as sp

from vi_core import Box, Free, MixedVI, NonNegative, product


def laplacian(k: int) -> sp.csr_matrix:
    """5-point Laplacian on a k × k grid (Dirichlet), (k², k²)."""
    T = sp.diags([-np.ones(k - 1), 2 * np.ones(k), -np.ones(k - 1)], [-1, 0, 1])
    eye = sp.identity(k)
    return (sp.kron(T, eye) + sp.kron(eye, T)).tocsr()


def coupled_grid_vi(rng: np.random.Generator, k: int, rho: float) -> MixedVI:
    """A piezo-like VI: A = [[L, ρLᵀ], [−ρL, L]] on two k × k grid fields, dual-mortar-like B on
    the first grid row of field a (private column j, coupled to the node above), random set."""
    L = laplacian(k)
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


def lower_vi(rng: np.random.Generator, k: int) -> MixedVI:
    """Two k × k grid fields, A = [[L, 0], [−ρL, 2L]] block lower triangular with symmetric
    diagonal blocks (so hierarchies of one level, a direct coarse solve, are exact inverses);
    B: on the first grid row of field a, a private column (weight in 0.5 … 2) and a coupling to
    two nodes of the next row (the master side)."""
    L = laplacian(k)
    n1 = k * k
    A = sp.bmat([[L, None], [-rng.uniform(0.1, 3.0) * L, 2 * L]]).tocsr()
    rows = np.arange(k)
    cols = np.concatenate([rows, rows + k, (rows + 1) % k + k])
    vals = np.concatenate([rng.uniform(0.5, 2.0, k), -rng.uniform(0.1, 1.0, 2 * k)])
    B = sp.csr_matrix((vals, (np.tile(rows, 3), cols)), shape=(k, 2 * n1))
    fields = {"a": np.arange(n1), "b": np.arange(n1, 2 * n1)}
    return MixedVI(A, B, np.ones(2 * n1), Box(-1.0, 1.0, size=k), fields=fields)


def newton_matrix(vi: MixedVI, cond, tied: np.ndarray, J=None, W=None) -> sp.csr_matrix:
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
