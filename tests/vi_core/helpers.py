"""Shared helpers of the vi_core tests."""

import numpy as np

from vi_core import MixedVI

TOL = 1e-10  # every solver is asked for this relative natural-map residual
ACCEPT = 1e-9  # … and must reach at least this one
AGREE = 1e-6  # relative distance between solutions (solver vs solver, solver vs exact)
FAST = {"linear_solver": "splu"}  # see the report: pypardiso's constructor costs ~0.5 s


def scales(vi: MixedVI) -> tuple[float, float]:
    """Data-implied magnitudes of u and λ: ‖f‖/‖A‖₂ and ‖f‖/‖B‖₂ (for all-zero solutions)."""
    nf = float(np.linalg.norm(vi.f))
    nb = np.linalg.norm(vi.B.toarray(), 2) if vi.m else 1.0
    return nf / np.linalg.norm(vi.A.toarray(), 2), nf / nb


def rel(a: np.ndarray, b: np.ndarray, scale: float) -> float:
    """‖a − b‖ / max(‖a‖, ‖b‖, 1e-6·scale): relative, except when both are (nearly) zero,
    e.g. λ = 0 when no constraint is active, where 1e-6·scale keeps it meaningful."""
    den = max(float(np.linalg.norm(a)), float(np.linalg.norm(b)), 1e-6 * scale)
    return float(np.linalg.norm(a - b)) / den


def agree(vi: MixedVI, a, b) -> tuple[float, float]:
    """(rel Δu, rel Δλ) between two solutions (objects with .u and .lam) of `vi`."""
    su, sl = scales(vi)
    return rel(a.u, b.u, su), rel(a.lam, b.lam, sl)


def applicable(vi: MixedVI) -> list[str]:
    """The methods that apply to `vi` (the conic path needs symmetric or skew-coupled A)."""
    methods = ["ssn", "homotopy"]
    if vi.structure != "general":
        methods.append("conic")
    return methods
