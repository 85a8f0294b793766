"""Inexact Newton: how accurately each Newton step's linear system is solved on the iterative
path (`vi_core.krylov`).

Each step starts from the current iterate and stops when the linear residual is ≤ η_k times its
initial value (Eisenstat–Walker, choice 2: η_k = 0.9 (F_k/F_{k−1})², at most ETA_MAX from a
cold start; from a warm start ETA_MAX_WARM = 0: nested iteration's prediction of the active set
usually holds, and then one step solved to tol is the answer; it applies to every warm start —
load-path steps, homotopy steps, the Coulomb fixed point's inner solves, conic's polish — and on
`mixvi solve shear_strip_path --level 3 --linear-solver amg` it takes mostly 1 Newton step per
load step where 1e-8 took 2 and 0.1 took 3, at the same wall time), but never asks for more than
0.1·tol relative to ‖b‖: the step that brings the natural residual below tol is solved to about
the requested tolerance, and convergence is judged from the natural residual of the iterate
itself, as with a direct solve.
"""

from __future__ import annotations

# the loosest relative linear tolerance of a Newton step, from a cold start and from a warm
# start (u0/λ0 given: nested iteration, where the active set is nearly right and Newton needs
# one exact step, so an inexact step only adds steps: 0 = every warm step is solved to the
# requested tolerance, 0.1·tol·‖b‖). Measured with the fine level of the paper scene (GMRES
# iterations / Newton steps): level 3 cold, 0.1 → 78 / 9, 1e-3 → 97 / 7; level 4 nested,
# 1e-4 → 98 / 4, 1e-8 → 71 / 2; with the warm start's stick/slip prediction at the transitions
# (the 2D contact plug-in's warm_start) level 4 nested, 1e-8 → 13 + 6 its in 2 steps, 0 → 18
# in 1 step, 3.13 s → 3.04 s (each step also costs a K_SS factorisation, residuals and the line
# search)
ETA_MAX = 0.1
ETA_MAX_WARM = 0.0


def forcing_term(res: float, res_prev: float | None, tol: float, eta_max: float = ETA_MAX) -> float:
    """Eisenstat–Walker (choice 2, γ = 0.9, α = 2) forcing term for the next Newton step:
    η = 0.9 (res / res_prev)², at most eta_max (also on the first step, res_prev None), and not
    below 0.1·tol/res (no step solved more accurately than reaching tol needs, whatever
    eta_max: with eta_max = 0 every step is solved to that floor)."""
    eta = eta_max if not res_prev else 0.9 * (res / res_prev) ** 2
    floor = 0.1 * tol / res if res > 0 else eta_max
    return float(max(min(eta_max, eta), floor))
