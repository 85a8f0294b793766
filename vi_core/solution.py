"""The record every solver returns."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Solution:
    """Result of `vi_core.solve`.

    u, lam : the solution in the caller's variables.
    converged : the natural-map residual reached `tol`.
    iterations : outer iterations (Newton steps, fixed-point steps, or conic solves).
    residual : relative natural-map residual at (u, lam) (`MixedVI.residual`).
    history : relative residual after each outer iteration (history[0] at the initial guess).
    time : wall-clock seconds.
    info : solver-specific details (active sets, levels, contraction rates, statuses, …).
    """

    u: np.ndarray
    lam: np.ndarray
    converged: bool
    iterations: int
    residual: float
    history: list[float]
    time: float
    method: str
    info: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @classmethod
    def of(
        cls,
        method: str,
        u: np.ndarray,
        lam: np.ndarray,
        residual: float,
        converged: bool,
        iterations: int,
        history: list[float],
        t0: float,
        **details,
    ) -> Solution:
        """A solver's record: `time` the seconds since `t0` (`time.perf_counter()`), residual
        and converged as plain float and bool; details: info, warnings."""
        res, ok, elapsed = float(residual), bool(converged), time.perf_counter() - t0
        return cls(u, lam, ok, iterations, res, history, elapsed, method, **details)
