"""Shared helpers of the vi_core tests."""

import numpy as np
from hypothesis import event

from vi_core import MixedVI

TOL = 1e-10  # every solver is asked for this relative natural-map residual
ACCEPT = 1e-9  # … and must reach at least this one
AGREE = 1e-6  # relative distance between solutions (solver vs solver, solver vs exact)
FAST = {"linear_solver": "splu"}  # small problems: SuperLU has the least overhead


def scales(vi: MixedVI) -> tuple[float, float]:
    """Data-implied magnitudes of u and λ: ‖f‖/‖A‖₂ and ‖f‖/‖B‖₂ (for all-zero solutions)."""
    nf = float(np.linalg.norm(vi.f))
    nb = np.linalg.norm(vi.B.toarray(), 2) if vi.m else 1.0
    return nf / np.linalg.norm(vi.A.toarray(), 2), nf / nb


def rel(a: np.ndarray, b: np.ndarray, scale: float) -> float:
    """‖a − b‖ / max(‖a‖, ‖b‖, 1e-3·scale): relative, except when both are (nearly) zero,
    e.g. λ = 0 when no constraint is active. Then a relative error is undefined and the check
    becomes absolute: ‖a − b‖ ≤ AGREE · 1e-3 · scale = 1e-9 · scale, which is what a residual
    tolerance of 1e-10 can deliver (an interior point λ = 3e-12 against an exact 0 is correct)."""
    den = max(float(np.linalg.norm(a)), float(np.linalg.norm(b)), 1e-3 * scale)
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


def record(vi: MixedVI, kind: np.ndarray | None = None) -> None:
    """Hypothesis events (shown by --hypothesis-show-statistics): what the draw covers."""
    event(f"structure={vi.structure}")
    for b in vi.Lambda.blocks():
        event(f"set={type(b).__name__}")
    rho = vi.info.get("rho", 0.0) if vi.structure != "symmetric" else 0.0
    event(f"rho in [{np.floor(rho)}, {np.floor(rho) + 1})" if rho else "rho=0")
    if kind is not None and (kind == "degenerate").any():
        event("has degenerate coordinates")
