"""Shared helpers of the vi_core tests."""

import numpy as np

from vi_core import MixedVI

TOL = 1e-10  # every solver is asked for this relative natural-map residual
ACCEPT = 1e-9  # … and must reach at least this one
AGREE = 1e-6  # relative distance between solutions (solver vs solver, solver vs exact)
FAST = {"linear_solver": "splu"}  # see the report: pypardiso's constructor costs ~0.5 s


def rel(a: np.ndarray, ref: np.ndarray) -> float:
    """‖a − ref‖ / ‖ref‖ (absolute when ref = 0)."""
    d = float(np.linalg.norm(ref))
    return float(np.linalg.norm(a - ref)) / (d if d > 0 else 1.0)


def applicable(vi: MixedVI) -> list[str]:
    """The methods that apply to `vi` (the conic path needs symmetric or skew-coupled A)."""
    methods = ["ssn", "homotopy"]
    if vi.structure != "general":
        methods.append("conic")
    return methods
