"""The constants of Section 3 for a discrete problem, in the norms of Gram matrices X and Y.

With ‖v‖_X² = vᵀXv and ‖μ‖_Y² = μᵀYμ, a(u, v) = vᵀAu and b(v, μ) = μᵀBv:

* m_a (3.2) = λ_min(X^{-1/2} A_0 X^{-1/2}) (coercivity, A_0 the symmetric part),
* M_a (3.1) = ‖X^{-1/2} A X^{-1/2}‖₂ (continuity; the largest singular value),
* M_b (3.3) = ‖Y^{-1/2} B X^{-1/2}‖₂,
* α (3.4) = σ_min(Y^{-1/2} B X^{-1/2}) = sqrt(λ_min(B X^{-1} Bᵀ, Y)) (discrete inf-sup),
* ρ = ‖A_0^{-1/2} C A_0^{-1/2}‖₂ (the homotopy rate per unit step; X-independent),
* t_0 (3.11) = α m_a / (M_a (α + m_a + 2 M_a)),
* the stability constant of (3.5) (α + m_a + 2 M_a) / (α m_a).

**Dual norm of the right-hand side.** The paper writes (f, v)_X; in matrix form the load
vector is f_vec = X f_riesz, so ‖f‖ in (3.5) is ‖f_riesz‖_X = sqrt(f_vecᵀ X^{-1} f_vec)
(`Constants.dual_norm_x`), the norm of f_vec in the dual space X'.

Small problems (n ≤ `dense_limit`) use dense eigen/singular value decompositions; larger ones
use ARPACK (`eigsh`) with factorised operators (shift-invert for the smallest eigenvalues).
Above `max_size` unknowns `constants` refuses (ValueError) rather than run for hours.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .linalg import Factorization
from .problem import MixedVI

MAX_SIZE = 200_000
DENSE_LIMIT = 1500


@dataclass(frozen=True)
class Constants:
    """The constants of Theorem 3.1 / Lemma 3.3 for one discrete problem (module docstring)."""

    m_a: float
    M_a: float
    M_b: float
    alpha: float
    rho: float
    t0: float
    stability: float
    X: sp.csr_matrix  # (n, n) Gram matrix of X
    Y: sp.csr_matrix  # (m, m) Gram matrix of Y

    def norm_x(self, v: np.ndarray) -> float:
        """‖v‖_X = sqrt(vᵀ X v)."""
        return float(np.sqrt(max(v @ (self.X @ v), 0.0)))

    def norm_y(self, mu: np.ndarray) -> float:
        """‖μ‖_Y = sqrt(μᵀ Y μ)."""
        return float(np.sqrt(max(mu @ (self.Y @ mu), 0.0)))

    def dual_norm_x(self, f: np.ndarray) -> float:
        """‖f‖_{X'} = sqrt(fᵀ X^{-1} f): the X-norm of the Riesz representative of f."""
        x = Factorization(self.X, "splu")(f)
        return float(np.sqrt(max(f @ x, 0.0)))


def _gram(G: Any, size: int, name: str) -> sp.csr_matrix:
    if G is None:
        return sp.identity(size, format="csr")
    if callable(G):  # a function assembling it when needed (`MixedVI.X`)
        G = G()
    G = sp.csr_matrix(G, dtype=float)
    if G.shape != (size, size):
        raise ValueError(f"{name} must be {size}×{size}, got {G.shape}")
    return G


def _op(n: int, fn: Callable[[np.ndarray], np.ndarray]) -> spla.LinearOperator:
    return spla.LinearOperator((n, n), matvec=fn, dtype=float)


def _largest(op, M, Minv) -> float:
    """Largest eigenvalue of op x = μ M x (op symmetric positive semidefinite).

    Relative accuracy 1e-8 with a 40-vector Krylov space: the top of a finite element spectrum
    is clustered, and at tol 1e-10 with ARPACK's default space the iteration took > 10 min at
    n = 4e3 (obstacle, level 3); constants need no more than a few digits.
    """
    n = op.shape[0]
    ncv = min(n, 40) if n > 2 else None
    return float(spla.eigsh(op, k=1, M=M, Minv=Minv, which="LA", tol=1e-8, ncv=ncv)[0][0])


def skew_ratio(
    A0: sp.spmatrix, C: sp.spmatrix, dense_limit: int = DENSE_LIMIT, backend: str = "auto"
) -> float:
    """ρ = ‖A_0^{-1/2} C A_0^{-1/2}‖₂: sqrt of the largest μ in Cᵀ A_0^{-1} C x = μ A_0 x.

    Invariant under any congruence (change of variables), hence under equilibration.
    """
    C = sp.csr_matrix(C)
    n = C.shape[0]
    if C.nnz == 0 or abs(C).max() == 0:
        return 0.0
    if n <= dense_limit:
        L = np.linalg.cholesky(sp.csr_matrix(A0).toarray())
        W = sla.solve_triangular(L, C.toarray(), lower=True)  # L^{-1} C
        M = sla.solve_triangular(L, W.T, lower=True).T  # (n, n) L^{-1} C L^{-T}
        return float(np.linalg.norm(M, 2))
    solve0 = Factorization(A0, backend)
    Ct = sp.csr_matrix(C.T)
    op = _op(n, lambda x: Ct @ solve0(C @ x))
    return float(np.sqrt(max(_largest(op, sp.csr_matrix(A0), _op(n, solve0)), 0.0)))


def constants(
    vi: MixedVI,
    X: Any = None,
    Y: Any = None,
    max_size: int = MAX_SIZE,
    dense_limit: int = DENSE_LIMIT,
) -> Constants:
    """m_a, M_a, M_b, α, ρ, t_0 and the (3.5) constant of `vi` in the norms of X and Y.

    X, Y : Gram matrices (default `vi.X`, `vi.Y`, else the identity).
    max_size : refuse (ValueError) when n + m exceeds it (default 200 000).
    dense_limit : dense decompositions up to this n, ARPACK with factorisations above.
    """
    n, m = vi.n, vi.m
    if n + m > max_size:
        raise ValueError(
            f"constants: n + m = {n + m} exceeds max_size = {max_size}; "
            "pass a larger max_size explicitly if the eigen solves are affordable"
        )
    X = _gram(vi.X if X is None else X, n, "X")
    Y = _gram(vi.Y if Y is None else Y, m, "Y")
    if n <= dense_limit:
        m_a, M_a, M_b, alpha = _dense(vi, X, Y)
    else:
        m_a, M_a, M_b, alpha = _sparse(vi, X, Y)
    rho = skew_ratio(vi.A0, vi.C, dense_limit=dense_limit)
    if m == 0:  # no constraint: α = ∞, the bounds reduce to their α → ∞ limits
        t0, stab = m_a / M_a, 1.0 / m_a
    else:
        t0 = alpha * m_a / (M_a * (alpha + m_a + 2.0 * M_a))
        stab = (alpha + m_a + 2.0 * M_a) / (alpha * m_a)
    return Constants(m_a, M_a, M_b, alpha, rho, t0, stab, X, Y)


def _dense(vi: MixedVI, X: sp.csr_matrix, Y: sp.csr_matrix) -> tuple[float, float, float, float]:
    Lx = np.linalg.cholesky(X.toarray())
    W = sla.solve_triangular(Lx, vi.A.toarray(), lower=True)
    At = sla.solve_triangular(Lx, W.T, lower=True).T  # (n, n) X^{-1/2} A X^{-1/2}
    # m_a = 1 / λ_max(X, A0): the largest eigenvalue of the pencil is relatively accurate even
    # when A0 mixes scales (stiffness 1e11 beside permittivity 1e-8), unlike λ_min of
    # X^{-1/2} A0 X^{-1/2}, whose absolute error ε‖A0‖ can exceed m_a itself
    # driver "gvd" (all eigenvalues, divide and conquer): the subset driver "gvx" failed to
    # converge on a drawn test problem
    top = sla.eigh(X.toarray(), vi.A0.toarray(), eigvals_only=True, driver="gvd")[-1]
    m_a = float(1.0 / top)
    M_a = float(np.linalg.norm(At, 2))
    if vi.m == 0:
        return m_a, M_a, 0.0, np.inf
    Ly = np.linalg.cholesky(Y.toarray())
    W = sla.solve_triangular(Ly, vi.B.toarray(), lower=True)  # (m, n) Y^{-1/2} B
    Bt = sla.solve_triangular(Lx, W.T, lower=True).T  # (m, n) Y^{-1/2} B X^{-1/2}
    sv = np.linalg.svd(Bt, compute_uv=False)
    alpha = float(sv[-1]) if vi.m <= vi.n else 0.0
    return m_a, M_a, float(sv[0]), alpha


def _sparse(vi: MixedVI, X: sp.csr_matrix, Y: sp.csr_matrix) -> tuple[float, float, float, float]:
    n, m = vi.n, vi.m
    A, B = vi.A, vi.B
    At, Bt = sp.csr_matrix(A.T), sp.csr_matrix(B.T)
    solve_x = Factorization(X)
    Xinv = _op(n, solve_x)
    # m_a = 1 / λ_max(X, A0), relatively accurate across mixed scales (see _dense)
    solve_a0 = Factorization(vi.A0)
    top = spla.eigsh(X, k=1, M=vi.A0, Minv=_op(n, solve_a0), which="LA", tol=1e-10)[0][0]
    m_a = float(1.0 / top)
    M_a = float(np.sqrt(_largest(_op(n, lambda x: At @ solve_x(A @ x)), X, Xinv)))
    if m == 0:
        return m_a, M_a, 0.0, np.inf
    S = _op(m, lambda y: B @ solve_x(Bt @ y))  # B X^{-1} Bᵀ
    M_b = float(np.sqrt(_largest(S, Y, _op(m, Factorization(Y)))))
    # S^{-1} r through the saddle-point matrix [[X, Bᵀ], [B, 0]]: y = S^{-1} r
    kkt = Factorization(sp.bmat([[X, Bt], [B, None]], format="csr"))
    S_inv = _op(m, lambda r: kkt(np.concatenate([np.zeros(n), -r]))[n:])
    mu = spla.eigsh(S, k=1, M=Y, sigma=0.0, which="LM", OPinv=S_inv, tol=1e-10)[0][0]
    return m_a, M_a, M_b, float(np.sqrt(max(mu, 0.0)))
