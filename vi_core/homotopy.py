"""The homotopy fixed point of Lemma 3.3, with nested levels.

a_r = a_0 + r·c: A_r = A_0 + r C (A_0 symmetric part, C skew part). For levels τ < s the map

    T(w) = S_τ(f − (s − τ) C w),     S_τ(g) = the u of the level-τ VI  A_τ u + Bᵀλ = g, …

has the level-s solution as its fixed point. S_τ is non-expansive from the A_0^{-1} norm of the
right-hand side to the A_0 energy norm of u (Lemma 3.2's argument with a_τ(v, v) = a_0(v, v)),
so T contracts with factor (s − τ)ρ in the energy norm, ρ = ‖A_0^{-1/2} C A_0^{-1/2}‖₂
(`constants.skew_ratio`, measured on the discrete problem).

**Levels.** With a target factor t (`rate`, default 0.7) take L = max(1, ⌈ρ/t⌉) levels
s_k = k/L, so each step contracts by ρ/L ≤ t. Level 0 is a symmetric VI solved by an oracle
(`inner="ssn"` or `"conic"`). Level k > 0 is solved by the fixed point above with τ = s_{k−1},
whose map evaluates S_{s_{k−1}} — itself a level-(k−1) fixed point (nesting). ρ < t needs one
level; strong coupling needs several and the cost multiplies level by level: that is the
measured price of this method (`info["levels"]`).

**Inexactness.** Every level is warm-started from the current iterate, and level k asks level
k − 1 for the absolute residual max(η · r_k, tol_k/10), r_k its own current absolute residual
(η = `eta`; absolute, because the right-hand sides f − (s − τ)C w of the levels differ in size).
Every level stops on its own natural-map residual; the top level (A_1 = A) stops on the full
problem's residual ≤ tol. Everything runs on `vi.equilibrated`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from .constants import constants, skew_ratio
from .problem import MixedVI, natural_residual
from .solution import Solution

INNER = ("ssn", "conic")


@dataclass
class _Level:
    """Bookkeeping of one level s_k."""

    s: float
    A: sp.csr_matrix  # (n, n) A_0 + s C
    iterations: int = 0  # fixed-point iterations (oracle calls at level 0)
    calls: int = 0  # solves requested from this level
    rates: list[float] = field(default_factory=list)  # ‖Δ_{j+1}‖/‖Δ_j‖ in the A_0 norm


def _level_residual(e: MixedVI, A: sp.csr_matrix, g: np.ndarray, u, lam) -> float:
    """Absolute natural-map residual ‖(r1, r2)‖₂ of (u, λ) for A u + Bᵀλ = g, Bu − gap ∈ N_Λ(λ)."""
    r1 = A @ u + e.B.T @ lam - g
    r2 = lam - e.Lambda.project(lam + (e.B @ u - e.gap))  # as in natural_residual
    return float(np.hypot(np.linalg.norm(r1), np.linalg.norm(r2)))


def _scale(e: MixedVI, g: np.ndarray) -> float:
    """The normalisation of `Residual.relative` for right-hand side g."""
    return max(float(np.linalg.norm(g)), float(np.linalg.norm(e.gap))) or 1.0


class _Homotopy:
    """Nested fixed-point solver on the equilibrated VI `e`."""

    def __init__(self, e: MixedVI, levels: list[float], inner: str, eta: float, options: dict):
        self.e = e
        self.C = e.C
        self.A0 = e.A0
        self.level0 = MixedVI(A=e.A0, B=e.B, f=e.f, Lambda=e.Lambda, gap=e.gap)
        # the top level is the full problem: use A itself (A_0 + C differs by rounding)
        self.levels = [_Level(s, e.A if s == 1.0 else (e.A0 + s * e.C).tocsr()) for s in levels]
        self.inner, self.eta, self.options = inner, eta, options
        self.max_iter = options.pop("max_iter")

    def energy(self, v: np.ndarray) -> float:
        return float(np.sqrt(max(v @ (self.A0 @ v), 0.0)))

    def oracle(self, g, u, lam, tol):
        """Level-0 (symmetric) solve with right-hand side g to absolute residual tol."""
        self.levels[0].calls += 1
        self.levels[0].iterations += 1
        vi0 = self.level0.with_rhs(f=g)
        if self.inner == "ssn":
            from .ssn import solve_ssn

            sol = solve_ssn(vi0, tol=tol / _scale(self.e, g), u0=u, lam0=lam, **self.options)
        else:
            from .conic import solve_conic

            sol = solve_conic(vi0, tol=tol / _scale(self.e, g), **self.options)
        return sol.u, sol.lam

    def solve(self, k: int, g, u, lam, tol, history: list[float] | None = None):
        """Solve level k with right-hand side g to absolute residual tol from (u, λ)."""
        if k == 0:
            return self.oracle(g, u, lam, tol)
        lev, below = self.levels[k], self.levels[k - 1]
        lev.calls += 1
        step = lev.s - below.s
        res = _level_residual(self.e, lev.A, g, u, lam)
        prev = None
        for _ in range(self.max_iter):
            if res <= tol:
                break
            inner_tol = max(self.eta * res, 0.1 * tol)
            u_new, lam_new = self.solve(k - 1, g - step * (self.C @ u), u, lam, inner_tol)
            size = self.energy(u_new - u)
            if prev:
                lev.rates.append(size / prev)
            prev = size
            u, lam = u_new, lam_new
            lev.iterations += 1
            res = _level_residual(self.e, lev.A, g, u, lam)
            if history is not None:
                history.append(res / _scale(self.e, g))
        return u, lam


REPORT_CONSTANTS_MAX_M = 1000  # contact scenes (m ≤ ~500) take seconds; obstacle m = n did not


def solve_homotopy(
    vi: MixedVI,
    tol: float = 1e-10,
    inner: str = "ssn",
    rate: float = 0.7,
    eta: float = 0.1,
    max_iter: int = 200,
    max_levels: int = 8,
    u0: np.ndarray | None = None,
    lam0: np.ndarray | None = None,
    report_constants: bool = True,
    **inner_options: Any,
) -> Solution:
    """Homotopy fixed point of Lemma 3.3 for `vi` (see module docstring).

    inner : level-0 oracle, "ssn" (default) or "conic". rate : target contraction factor
        (s − τ)ρ per level (0 < rate < 1). eta : relative inner accuracy. max_iter :
        fixed-point iterations per level solve. max_levels : refuse (a non-converged
        Solution with a warning, nothing computed) when ⌈ρ/rate⌉ exceeds it; measured cost
        ≈ 2–3× more oracle calls per extra level (ρ = 3: 5 levels, ~450 calls).
    u0, lam0 : initial guess (physical variables).
    report_constants : also compute m_a, M_a, α and the paper's t_0 bound (3.11) (dense or
        ARPACK eigen solves) and put them in `info`.
    inner_options : passed to the oracle unchanged (e.g. linear_solver, clarabel).
    """
    if inner not in INNER:
        raise ValueError(f"inner oracle {inner!r} unknown; allowed: {', '.join(INNER)}")
    if not 0 < rate < 1:
        raise ValueError(f"rate must lie in (0, 1), got {rate}")
    t0 = time.perf_counter()
    e = vi.equilibrated
    sc = vi.scaling
    rho = 0.0 if vi.structure == "symmetric" else skew_ratio(e.A0, e.C)
    n_levels = max(1, math.ceil(rho / rate)) if rho > 0 else 0
    u = np.zeros(e.n) if u0 is None else np.asarray(u0, float) / sc.s_u
    lam = np.zeros(e.m) if lam0 is None else np.asarray(lam0, float) / sc.s_lam
    history = [natural_residual(e, u, lam).relative]
    if n_levels > max_levels:
        info = {"rho": rho, "levels_needed": n_levels, "max_levels": max_levels}
        refusal = (
            f"homotopy: ρ = {rho:.3g} needs {n_levels} levels at rate {rate} "
            f"(> max_levels = {max_levels}); the nested cost grows geometrically with "
            'the number of levels: not attempted (use method="ssn")'
        )
        u, lam = sc.to_physical(u, lam)
        return Solution.of(
            "homotopy", u, lam, history[0], False, 0, history, t0, info=info, warnings=[refusal]
        )
    levels = [k / n_levels for k in range(n_levels + 1)] if n_levels else [0.0]
    solver = _Homotopy(e, levels, inner, eta, {**inner_options, "max_iter": max_iter})
    if n_levels == 0:
        u, lam = solver.oracle(e.f, u, lam, tol * _scale(e, e.f))
        history.append(natural_residual(e, u, lam).relative)
    else:
        u, lam = solver.solve(n_levels, e.f, u, lam, tol * _scale(e, e.f), history)
    res = natural_residual(e, u, lam).relative
    top = solver.levels[-1]
    info: dict[str, Any] = {
        "rho": rho,
        "levels": levels,
        "rate_bound": rho / n_levels if n_levels else 0.0,
        "inner": inner,
        "oracle_calls": solver.levels[0].calls,
        "per_level": [
            {
                "s": lev.s,
                "calls": lev.calls,
                "iterations": lev.iterations,
                "rate_median": float(np.median(lev.rates)) if lev.rates else None,
                "rate_max": float(np.max(lev.rates)) if lev.rates else None,
            }
            for lev in solver.levels
        ],
        "rates": list(top.rates) if n_levels else [],
    }
    if report_constants and vi.m > REPORT_CONSTANTS_MAX_M:
        info["t0_paper"] = (
            f"not computed: m = {vi.m} > {REPORT_CONSTANTS_MAX_M} multipliers (the sparse "
            "eigen solves took over 10 minutes at m = n = 3969; call vi_core.constants(vi))"
        )
    elif report_constants:
        try:
            c = constants(vi)
            info.update(m_a=c.m_a, M_a=c.M_a, alpha=c.alpha, t0_paper=c.t0)
        except ValueError as err:
            info["t0_paper"] = f"not computed: {err}"
    converged = res <= tol
    u, lam = sc.to_physical(u, lam)
    iterations = top.iterations if n_levels else 1
    sol = Solution.of("homotopy", u, lam, res, converged, iterations, history, t0, info=info)
    if not converged:
        sol.warnings.append(
            f"homotopy: residual {res:.3e} did not reach tol {tol:.1e} "
            f"({sol.iterations} top-level iterations, {len(levels) - 1} levels)"
        )
    return sol
