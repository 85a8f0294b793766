"""The checks of the fault table (README "What catches which fault"), as functions: the
conformance battery asserts that they pass, tests/problems/plugins/contact/test_fault_table.py
that each fails under the fault it is meant to catch."""

from __future__ import annotations

import vi_core
from problems.commands.study import run_study
from problems.plugins.contact import balance as piezo_balance
from problems.plugins.contact import plane as pc
from problems.scene import load_scene
from problems.scene.exact import split_exact

# README, scene `manufactured`: fitted rates over levels 2–4 against the exact solution, norms
# of problems/plugins/contact/errors.py (u in H¹, φ in H¹, λ in the h^{1/2}-weighted L²)
MANUFACTURED_RATES = {"u_H1": 1.00, "phi_H1": 1.09, "lam": 1.43}
MANUFACTURED_LEVELS = [2, 3, 4]
RATE_WITHIN = 0.1


# README, scene `curved_manufactured` (two bodies, curved non-matching interface, tied):
# fitted over levels 1–3 against the exact solution
CURVED_RATES = {"u_H1": 1.02, "lam": 1.50}
CURVED_LEVELS = [1, 2, 3]


def curved_rates() -> dict[str, float]:
    """Observed rates of the curved two-body manufactured scene (ssn, levels 1–3)."""
    result = run_study(
        load_scene("curved_manufactured"), CURVED_LEVELS, ["ssn"], [1e-12], progress=False
    )
    return result["rates"]["ssn"]


def manufactured_rates() -> dict[str, float]:
    """Observed rates of the manufactured scene (ssn, tol 1e-12, levels 2–4)."""
    result = run_study(
        load_scene("manufactured"), MANUFACTURED_LEVELS, ["ssn"], [1e-12], progress=False
    )
    return result["rates"]["ssn"]


def rates_off(rates: dict[str, float], claimed: dict[str, float]) -> dict[str, float]:
    """The norms whose observed rate is more than RATE_WITHIN away from the claimed one."""
    return {k: rates[k] for k, v in claimed.items() if not abs(rates[k] - v) <= RATE_WITHIN}


def solved(name: str, level: int, overrides: tuple[str, ...] = ()):
    """(model, ssn solution) of a shipped scene (its [exact] table removed)."""
    scene, _ = split_exact(load_scene(name, list(overrides)))
    model = pc.build(scene, level)
    return model, vi_core.solve(model.vi, "ssn", tol=1e-12)


def force_imbalance(name: str, level: int) -> float:
    """Largest relative force imbalance of the bodies (piezo_balance.force_balance)."""
    return piezo_balance.force_balance(*solved(name, level))["imbalance"]


def lemma_gap(name: str, level: int) -> float:
    """Lemma 4.2 gap by quadrature (rigid foundation; piezo_balance.lemma_4_2)."""
    return piezo_balance.lemma_4_2(*solved(name, level))["gap"]


BALANCE_OK = 1e-10  # measured 4e-15 … 4e-14 on the shipped scenes (rounding)
LEMMA_OK = 1e-10  # measured 2e-16 (constant g) and 1.5e-13 (manufactured: quadrature of g)
