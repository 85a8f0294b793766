"""`solve(vi, method=...)`: one entry point for every solver.

Methods
-------
"ssn"       semismooth Newton / primal-dual active set (`vi_core.ssn.solve_ssn`): any A.
"conic"     cvxpy + Clarabel (`vi_core.conic.solve_conic`): symmetric or skew-coupled A only.
"homotopy"  nested fixed point of Lemma 3.3 (`vi_core.homotopy.solve_homotopy`): any A.
"auto"      the rule below.

**The "auto" rule.** Semismooth Newton first: it handles every structure and set and is the
fastest on the gallery problems (n ≤ 60: ~10–30 ms against ~70–300 ms for "conic" and
0.1–3 s for "homotopy"). Measured exception: a skew-coupled 1D problem with n = 42 000 and
SuperLU took 32 s with "ssn" (12 Newton steps) and 11 s with "conic" (10 interior point steps
and one polishing Newton step). Only if Newton fails to reach `tol` does "auto" fall back,
from a cold start: to "conic" when A is symmetric or skew-coupled (an interior point method
has no active-set cycling), else to "homotopy". `info["auto"]` records the choice and the
failed attempt's residual.
"""

from __future__ import annotations

from typing import Any

from .problem import MixedVI
from .solution import Solution

METHODS = ("auto", "ssn", "conic", "homotopy")


def _run(vi: MixedVI, method: str, tol: float, options: dict[str, Any]) -> Solution:
    if method == "ssn":
        from .ssn import solve_ssn

        return solve_ssn(vi, tol=tol, **options)
    if method == "conic":
        from .conic import solve_conic

        return solve_conic(vi, tol=tol, **options)
    from .homotopy import solve_homotopy

    return solve_homotopy(vi, tol=tol, **options)


def solve(vi: MixedVI, method: str = "auto", tol: float = 1e-10, **options: Any) -> Solution:
    """Solve the mixed VI `vi` to relative natural-map residual `tol` (`MixedVI.residual`).

    method : "ssn", "conic", "homotopy" or "auto" (module docstring).
    options : passed to the chosen solver unchanged, e.g.
        ``solve(vi, "conic", clarabel={"max_iter": 50}, polish=0)``,
        ``solve(vi, "homotopy", inner="conic", rate=0.5)``,
        ``solve(vi, "ssn", linear_solver="splu", max_iter=30)``.
        With "auto" they go to semismooth Newton (and `linear_solver` also to the fallback).
    """
    if method not in METHODS:
        raise ValueError(f"method {method!r} unknown; allowed: {', '.join(METHODS)}")
    if not 0.0 < tol < 1.0:
        raise ValueError(f"tol = {tol!r}: a relative residual tolerance must lie in (0, 1)")
    if method != "auto":
        return _run(vi, method, tol, options)
    sol = _run(vi, "ssn", tol, options)
    sol.info["auto"] = {"chosen": "ssn"}
    if sol.converged:
        return sol
    fallback = "conic" if vi.structure in ("symmetric", "skew-coupled") else "homotopy"
    keep = {k: v for k, v in options.items() if k == "linear_solver"}
    alt = _run(vi, fallback, tol, keep)
    alt.info["auto"] = {"chosen": fallback, "ssn_residual": sol.residual}
    alt.warnings.insert(0, f"auto: ssn stopped at residual {sol.residual:.3e}; fell back")
    return alt if alt.residual < sol.residual else sol
