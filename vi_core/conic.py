"""The conic path: cvxpy + Clarabel on the equivalent convex program.

Symmetric A (A = A_0): the VI is the optimality system of

    min ½uᵀA u − fᵀu + Σ_blocks σ_Λb(z_b)   subject to   B u − gap = z,

σ the support function (g|z| for a Box(−g, g), Σ max(lo z, hi z) for a general Box, r‖z‖ for a
Ball, the constraint z ≤ 0 for NonNegative and z = 0 for Free). The multiplier λ is the dual
value cvxpy reports for the constraint `B @ u - gap == z` (stationarity in u reads
A u − f + Bᵀλ = 0 and in z: λ ∈ ∂σ_Λ(z), i.e. z ∈ N_Λ(λ)); the sign is pinned by
tests/vi_core/test_conic.py::test_dual_sign (`_DUAL_SIGN`).

Skew-coupled A = [[K, Gᵀ], [−G, P]] (split by `MixedVI.skew_split`, B acting on the first
block): the second block row −G u + P φ = f_φ is a linear constraint and the problem is exactly
the sparse QP

    min ½uᵀK u + ½φᵀP φ − f_uᵀu + σ_Λ(B u − gap)   subject to   P φ = G u + f_φ.

Its multiplier ψ of `P φ − G u == f_φ` satisfies P φ + P ψ = 0, so ψ = ∓φ and the first block
row of its optimality system is K u + Gᵀφ + Bᵀλ = f_u: the full non-symmetric VI, no Schur
complement. General non-symmetric A is refused (use method="homotopy").

Everything runs on `vi.equilibrated` (Clarabel equilibrates matrices, not right-hand sides),
**normalised**: the VI is positively homogeneous of degree 1 in its data — (u, λ) solves
(f, gap, Λ) iff (u/t, λ/t) solves (f/t, gap/t, Λ/t) — so the cone program is posed for the data
divided by t = max(‖f'‖_∞, ‖gap'‖_∞) (`_normalisation`) and its answer multiplied by t.
Clarabel's absolute tolerances then mean the same for loads × 1e-12 and × 1e12
(`info["normalisation"]` = t; tests/vi_core/test_conic.py::test_scale_invariance).

The answer is judged by the VI residual. **Polishing is a separate step**: if the interior point
result misses `tol`, at most `polish` semismooth-Newton steps warm-started from it are taken,
reported in `info["polish"]`; `info["conic_residual"]` is always the residual of Clarabel's raw
answer. Cross-checks (`mixvi check`) use `polish=0`: a polished answer is an ssn answer.
"""

from __future__ import annotations

import time
import warnings as warnings_module
from typing import Any

import numpy as np

from .marks import mark
from .problem import MixedVI, natural_residual
from .sets import Ball, Box, Free, NonNegative
from .solution import Solution

# Clarabel's tolerances (its own scaling). At 1e-10 its raw answers had natural-map residuals up
# to 2.4e-6 (antiplane_manufactured and signorini, level 2); at 1e-12 they are ≤ ~2e-9 for one
# or two more interior-point iterations (measured on the shipped scenes, `mixvi check`).
CLARABEL_DEFAULTS = {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12}
_DUAL_SIGN = 1.0  # λ = _DUAL_SIGN · (dual value of `B @ u - gap == z`), see test_dual_sign

_OK = ("optimal",)
_INACCURATE = ("optimal_inaccurate",)


def _normalisation(e: MixedVI) -> float:
    """t = max(‖f‖_∞, ‖gap‖_∞) of the equilibrated VI; if both vanish, the largest finite
    |bound| of Λ; 1 if that vanishes too. Bounds do not enter otherwise: loads scaled with the
    bounds scale t alike, while a bound far above the loads (a nearly tied problem) must not
    shrink the data Clarabel sees (measured: g varying 1e8 along Γ3 gave a raw residual 2.8e-6
    with the bounds in t, 6e-12 without). Not rounded to a power of two: data × s then give the
    same normalised data up to rounding for any s, hence the same Clarabel iterations."""
    t = max(float(np.max(np.abs(e.f), initial=0.0)), float(np.max(np.abs(e.gap), initial=0.0)))
    if t == 0.0:
        for block in e.Lambda.blocks():
            if isinstance(block, Box):
                bounds = np.abs(np.concatenate([block.lo, block.hi]))
                t = max(t, float(np.max(bounds[np.isfinite(bounds)], initial=0.0)))
            elif isinstance(block, Ball):
                t = max(t, float(np.max(block.radius, initial=0.0)))
    return t if t > 0 and np.isfinite(t) else 1.0


def _normalised(e: MixedVI, t: float) -> MixedVI:
    """The same VI with data f/t, gap/t and Λ/t (A and B unchanged)."""
    if t == 1.0:
        return e
    out = MixedVI(
        A=e.A,
        B=e.B,
        f=e.f / t,
        Lambda=e.Lambda.scaled(np.full(e.m, t)),
        gap=e.gap / t,
        info={"equilibrated": True, "normalised": t},
    )
    for name in ("A0", "C", "structure", "skew_split"):  # unchanged by the data: reuse
        out.__dict__[name] = getattr(e, name)
    return out


def _support_terms(z, e: MixedVI) -> tuple[list, list]:
    """σ_Λ(z) terms and the constraints z_b = 0 (Free), z_b ≤ 0 (NonNegative)."""
    terms, cons = [], []
    for block, s in zip(e.Lambda.blocks(), e.Lambda.slices(), strict=True):
        zb = z[s]
        if isinstance(block, Free):
            cons.append(zb == 0)
        elif isinstance(block, NonNegative):
            cons.append(zb <= 0)
        elif isinstance(block, Box | Ball):
            terms.append(block.support(zb))
        else:
            raise TypeError(f"the conic path does not know the set {block!r}")
    return terms, cons


def _program(cp, e: MixedVI):
    """The cvxpy problem for the equilibrated VI `e`.

    Returns (problem, variables, link): variables = (u,) for symmetric A, (u, φ, i1, i2) for
    skew-coupled A (i1, i2 the index sets of the two blocks); link the constraint
    `B @ u - gap == z` whose dual value is λ (None when m = 0).
    """
    structure = e.structure
    if structure == "general":
        raise ValueError(
            "the conic path needs a symmetric or skew-coupled A (A = [[K, Gᵀ], [−G, P]] with "
            "B on the first block); this A is a general non-symmetric matrix: use "
            'method="homotopy" (conic level-0 oracle: inner="conic") or method="ssn"'
        )
    n, m = e.n, e.m
    z = cp.Variable(m) if m else None
    if structure == "symmetric":
        u = cp.Variable(n)
        obj = 0.5 * cp.quad_form(u, cp.psd_wrap(e.A0)) - e.f @ u
        cons = []
        x_of = (u,)
    else:
        first = e.skew_split
        i1, i2 = np.flatnonzero(first), np.flatnonzero(~first)
        A = e.A.tocsr()
        K, P = e.A0[i1][:, i1], e.A0[i2][:, i2]
        G = -A[i2][:, i1]  # (n2, n1): second block row is −G u + P φ = f_φ
        u = cp.Variable(i1.size)
        phi = cp.Variable(i2.size)
        obj = (
            0.5 * cp.quad_form(u, cp.psd_wrap(K))
            + 0.5 * cp.quad_form(phi, cp.psd_wrap(P))
            - e.f[i1] @ u
        )
        cons = [P @ phi - G @ u == e.f[i2]]
        x_of = (u, phi, i1, i2)
    link = None
    if m:
        Bu = e.B @ u if structure == "symmetric" else e.B[:, x_of[2]] @ u
        link = Bu - e.gap == z
        terms, extra = _support_terms(z, e)
        obj = obj + sum(terms) if terms else obj
        cons = cons + [link] + extra
    return cp.Problem(cp.Minimize(obj), cons), x_of, link


def solve_conic(
    vi: MixedVI,
    tol: float = 1e-10,
    clarabel: dict[str, Any] | None = None,
    polish: int = 3,
    linear_solver: str = "auto",
) -> Solution:
    """Solve a symmetric or skew-coupled `vi` with cvxpy + Clarabel (see module docstring).

    clarabel : Clarabel settings, passed to ``cvxpy.Problem.solve(solver="CLARABEL", ...)``
        unchanged; they override `CLARABEL_DEFAULTS` (tolerances 1e-12).
    polish : maximum semismooth-Newton steps from the conic point if its residual misses
        `tol` (0 disables polishing).
    """
    import cvxpy as cp

    from .ssn import solve_ssn

    t0 = time.perf_counter()
    e = vi.equilibrated
    sc = vi.scaling
    history = [natural_residual(e, np.zeros(e.n), np.zeros(e.m)).relative]
    t_norm = _normalisation(e)
    prob, x_of, link = _program(cp, _normalised(e, t_norm))
    settings = {**CLARABEL_DEFAULTS, **(clarabel or {})}
    info: dict[str, Any] = {
        "structure": e.structure,
        "clarabel": settings,
        "normalisation": t_norm,
    }
    warnings: list[str] = []
    try:
        with warnings_module.catch_warnings():  # statuses are mapped below, not warned about
            warnings_module.simplefilter("ignore", UserWarning)
            mark("clarabel", vi.n)  # a test hook (vi_core.marks); nothing when unset
            prob.solve(solver=cp.CLARABEL, **settings)
        status = prob.status
    except cp.error.SolverError as err:
        status = f"solver_error: {err}"
    info["status"] = status
    stats = prob.solver_stats
    info["ipm_iterations"] = getattr(stats, "num_iters", None) if stats else None
    info["solve_time"] = getattr(stats, "solve_time", None) if stats else None
    if status not in _OK + _INACCURATE or x_of[0].value is None:
        msg = f"conic: Clarabel/cvxpy status {status!r}; no solution"
        u, lam = np.zeros(vi.n), np.zeros(vi.m)
        return Solution.of(
            "conic", u, lam, history[0], False, 1, history, t0, info=info, warnings=[msg]
        )
    if status in _INACCURATE:
        warnings.append(f"conic: Clarabel status {status!r}; judged by the VI residual")
    u = np.empty(e.n)
    if e.structure == "symmetric":
        u[:] = x_of[0].value
    else:
        u[x_of[2]] = x_of[0].value
        u[x_of[3]] = x_of[1].value
    lam = _DUAL_SIGN * np.asarray(link.dual_value, float).ravel() if e.m else np.zeros(0)
    u, lam = u * t_norm, lam * t_norm  # undo the normalisation
    res = natural_residual(e, u, lam).relative
    history.append(res)
    info["conic_residual"] = res
    iterations = 1
    if res > tol and polish > 0:
        u_phys, lam_phys = sc.to_physical(u, lam)
        pol = solve_ssn(
            vi, tol=tol, max_iter=polish, u0=u_phys, lam0=lam_phys, linear_solver=linear_solver
        )
        up, lp = sc.to_scaled(pol.u, pol.lam)
        size = max(float(np.linalg.norm(np.concatenate([u, lam]))), 1e-300)
        info["polish"] = {
            "steps": pol.iterations,
            "residual_before": res,
            "residual_after": pol.residual,
            "relative_change": float(np.linalg.norm(np.concatenate([up - u, lp - lam])) / size),
        }
        if pol.residual < res:
            u, lam, res = up, lp, pol.residual
        history.extend(pol.history[1:])
        iterations += pol.iterations
    converged = res <= tol
    if not converged:
        warnings.append(f"conic: residual {res:.3e} did not reach tol {tol:.1e}")
    u, lam = sc.to_physical(u, lam)
    return Solution.of(
        "conic", u, lam, res, converged, iterations, history, t0, info=info, warnings=warnings
    )
