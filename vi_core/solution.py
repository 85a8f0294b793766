"""The record every solver returns."""

from __future__ import annotations

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
