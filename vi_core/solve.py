"""`solve(vi, method=...)`: one entry point for every solver.

Methods
-------
"ssn"       semismooth Newton / primal-dual active set (`vi_core.ssn.solve_ssn`): any A.
"conic"     cvxpy + Clarabel (`vi_core.conic.solve_conic`): symmetric or skew-coupled A only.
"homotopy"  nested fixed point of Lemma 3.3 (`vi_core.homotopy.solve_homotopy`): any A.
"fixed_point"  contact sets only (vi_core.coulomb): the fixed point on Tresca problems
            g ← F λ_n (`vi_core.tresca_fixed_point.solve_tresca_fixed_point`), each Tresca
            problem solved by `inner` = "ssn", "homotopy" or "conic".
"auto"      the rule below.

**Quasi-variational sets** (`Coulomb`, `UnilateralTresca(contact_only=True)`: Λ depends on λ).
"ssn" applies unchanged (the Hüeber–Stadler–Wohlmuth semismooth Newton, vi_core.coulomb) and so
does "fixed_point"; "conic" and "homotopy" need a fixed convex set and are refused (reach them
as the inner solver of "fixed_point"). "auto" takes "ssn" and falls back to "fixed_point"
(inner "ssn") from a cold start. A VI with a contact set that is not quasi (Tresca everywhere)
takes "ssn", "fixed_point" (one Tresca problem) or "auto".

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

from .coulomb import ContactSet
from .problem import MixedVI
from .solution import Solution

METHODS = ("auto", "ssn", "conic", "homotopy")  # for fixed convex sets
CONTACT_METHODS = ("auto", "ssn", "fixed_point")  # for Λ with contact blocks (vi_core.coulomb)


def _run(vi: MixedVI, method: str, tol: float, options: dict[str, Any]) -> Solution:
    if method == "ssn":
        from .engine import ssn_loop

        return ssn_loop()(vi, tol=tol, **options)
    if method == "conic":
        from .conic import solve_conic

        return solve_conic(vi, tol=tol, **options)
    if method == "fixed_point":
        from .tresca_fixed_point import solve_tresca_fixed_point

        return solve_tresca_fixed_point(vi, tol=tol, **options)
    from .homotopy import solve_homotopy

    return solve_homotopy(vi, tol=tol, **options)


def solve(vi: MixedVI, method: str = "auto", tol: float = 1e-10, **options: Any) -> Solution:
    """Solve the mixed VI `vi` to relative natural-map residual `tol` (`MixedVI.residual`).

    method : "ssn", "conic", "homotopy", "fixed_point" or "auto" (module docstring).
    options : passed to the chosen solver unchanged, e.g.
        ``solve(vi, "conic", clarabel={"max_iter": 50}, polish=0)``,
        ``solve(vi, "homotopy", inner="conic", rate=0.5)``,
        ``solve(vi, "ssn", linear_solver="splu", max_iter=30)``,
        ``solve(vi, "fixed_point", inner="conic", max_iter=50)``.
        With "auto" they go to semismooth Newton (and `linear_solver` also to the fallback).
    """
    known = METHODS + ("fixed_point",)
    if method not in known:
        raise ValueError(f"method {method!r} unknown; allowed: {', '.join(known)}")
    if not 0.0 < tol < 1.0:
        raise ValueError(f"tol = {tol!r}: a relative residual tolerance must lie in (0, 1)")
    contact = any(isinstance(b, ContactSet) for b in vi.Lambda.blocks())
    if contact and method not in CONTACT_METHODS:
        raise ValueError(
            f"method {method!r} needs a fixed convex set; {vi.Lambda!r} holds contact blocks: "
            f'allowed: {", ".join(CONTACT_METHODS)} (fixed_point takes inner="{method}")'
        )
    if not contact and method not in METHODS:
        raise ValueError(
            f"method {method!r} iterates on contact blocks (vi_core.coulomb); {vi.Lambda!r} "
            f"has none: allowed: {', '.join(METHODS)}"
        )
    if method != "auto":
        return _run(vi, method, tol, options)
    sol = _run(vi, "ssn", tol, options)
    sol.info["auto"] = {"chosen": "ssn"}
    if sol.converged:
        return sol
    if contact:
        fallback = "fixed_point"
    else:
        fallback = "conic" if vi.structure in ("symmetric", "skew-coupled") else "homotopy"
    keep = {k: v for k, v in options.items() if k == "linear_solver"}
    alt = _run(vi, fallback, tol, keep)
    alt.info["auto"] = {"chosen": fallback, "ssn_residual": sol.residual}
    alt.warnings.insert(0, f"auto: ssn stopped at residual {sol.residual:.3e}; fell back")
    return alt if alt.residual < sol.residual else sol
