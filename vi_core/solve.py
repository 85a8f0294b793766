"""`solve(vi, method=...)`: one entry point for every solver."""

from __future__ import annotations

from typing import Any

from .problem import MixedVI
from .solution import Solution

METHODS = ("auto", "ssn")


def solve(vi: MixedVI, method: str = "auto", tol: float = 1e-10, **options: Any) -> Solution:
    """Solve the mixed VI `vi` to relative natural-map residual `tol`.

    method : "ssn" (semismooth Newton / primal-dual active set) or "auto".
    options : passed to the chosen solver unchanged.
    """
    if method not in METHODS:
        raise ValueError(f"method {method!r} unknown; allowed: {', '.join(METHODS)}")
    if method in ("auto", "ssn"):
        from .ssn import solve_ssn

        return solve_ssn(vi, tol=tol, **options)
    raise AssertionError(method)
