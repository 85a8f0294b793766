"""The fixed point on Tresca problems for quasi-variational contact sets (Coulomb).

For a VI whose Λ holds `ContactSet` blocks (vi_core.coulomb), iterate

    g^{j+1} = tresca_bound(λ_n^j)        (Coulomb: g = F λ_n^j; contact-only Tresca: g·[λ_n^j > 0])
    (u^{j+1}, λ^{j+1}) = the solution of the Tresca problem with the fixed bound g^{j+1},

starting from g^0 = tresca_bound(λ_n^0) (λ^0 = 0: the frictionless problem). Each Tresca problem
is an ordinary convex mixed VI: the rows of every contact block are reordered normals first, and
the block becomes `NonNegative(k) × Box(−g, g)` (dim 2) or `NonNegative(k) × Ball(g, 2)`
(dim 3), so it is solved by any of the existing solvers (`inner` = "ssn", "homotopy" or
"conic"; conic needs a symmetric or skew-coupled A).

**Contraction.** The map λ_n^j ↦ λ_n^{j+1} contracts when F is small (the classical existence
proof for small friction); its factor is *measured*: `info["rates"]` holds
‖λ_n^{j+1} − λ_n^j‖ / ‖λ_n^j − λ_n^{j−1}‖ (equilibrated variables of the original VI) and
`info["contraction"]` their median over the last half of the iterations.

**Stopping.** Converged when the natural-map residual of the *original* quasi-variational VI
(`MixedVI.residual`, the combined map of vi_core.coulomb) is ≤ tol. Not converged — with a
warning and `converged=False`, never as an answer — when an inner solve fails, when `max_iter`
is reached, or when the step does not shrink (ratio ≥ `NO_CONTRACTION`) `patience` times in a row
(divergence or a cycle: measured, e.g. a 2-cycle with ratio 1.0 on a gallery problem at F = 3).

**States confirmed.** The last Tresca answer's |λ_t| at a slipping node is F λ_n of the
previous iterate, short of F λ_n by the last step: at a loose tolerance its margin can read as
stick. So a converged answer's partition is checked by the rule every plug-in reports with
(`vi_core.states.vi_states`: multiplier margin and gap/slip, thresholds scaled by the achieved
residual, the stress threshold at least FACTOR times the last step's change of the bound —
the shortfall a slipping node's |λ_t| may have); while some node is ambiguous the iteration
goes on at a tolerance 10 times tighter, at most `TIGHTEN` times and not below `TIGHTEST`.
Still ambiguous: a warning (the states are reported ambiguous, never guessed); a tightened
round that fails keeps the confirmed answer.
`info["states"]` records each round (tolerance, residual, ambiguous nodes) and the counts.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from . import states as node_states
from .coulomb import ContactSet
from .problem import MixedVI
from .sets import Ball, Box, ConvexSet, NonNegative, product
from .solution import Solution

INNER = ("ssn", "homotopy", "conic")
NO_CONTRACTION = 0.999  # a step ratio at least this large counts as "not contracting"
# confirming the states: while the answer's partition has ambiguous nodes (vi_core.states),
# iterate on at a tolerance 10 times tighter, at most TIGHTEN times and not below TIGHTEST
TIGHTEN = 3
TIGHTEST = 1e-14


class TrescaSequence:
    """The Tresca problems of a VI with contact blocks: row order and sets for a given bound."""

    def __init__(self, vi: MixedVI):
        self.vi = vi
        self.perm = np.arange(vi.m)  # (m,) row of `vi` at each row of the Tresca problem
        self.contact: list[tuple[ContactSet, np.ndarray]] = []  # block, its normal rows in vi
        for block, s in zip(vi.Lambda.blocks(), vi.Lambda.slices(), strict=True):
            if isinstance(block, ContactSet):
                rows = np.arange(s.start, s.stop).reshape(block.k, block.dim)  # (k, dim)
                self.perm[s] = np.concatenate([rows[:, 0], rows[:, 1:].ravel()])
                self.contact.append((block, rows[:, 0]))
        if not self.contact:
            raise ValueError("the fixed point on Tresca problems needs a contact block in Λ")
        self.inverse = np.argsort(self.perm)  # (m,)
        self.normal = np.concatenate([rows for _, rows in self.contact])  # (k_total,)

    def problem(self, bounds: list[np.ndarray]) -> MixedVI:
        """The Tresca problem with bound g_b (k_b,) for each contact block b."""
        blocks: list[ConvexSet] = []
        it = iter(bounds)
        for block in self.vi.Lambda.blocks():
            if not isinstance(block, ContactSet):
                blocks.append(block)
                continue
            g = next(it)
            blocks.append(NonNegative(block.k))
            blocks.append(Box(-g, g) if block.dim == 2 else Ball(g, block.dim - 1))
        vi = self.vi
        return MixedVI(
            A=vi.A,
            B=vi.B[self.perm],
            f=vi.f,
            Lambda=product(*blocks),
            gap=vi.gap[self.perm],
            info={"tresca_of": vi.info.get("gallery", "")},
            partition=vi.partition,  # A by rows on an engine's processes
        )

    def bounds(self, lam: np.ndarray) -> list[np.ndarray]:
        """g_b = tresca_bound(λ_n) of each contact block at the multiplier λ (vi's rows)."""
        return [block.tresca_bound(lam[rows]) for block, rows in self.contact]


def _inner_solve(sub: MixedVI, inner: str, tol: float, u, lam, options: dict) -> Solution:
    if inner == "ssn":
        from .ssn import solve_ssn

        return solve_ssn(sub, tol=tol, u0=u, lam0=lam, **options)
    if inner == "homotopy":
        from .homotopy import solve_homotopy

        return solve_homotopy(sub, tol=tol, u0=u, lam0=lam, report_constants=False, **options)
    from .conic import solve_conic

    return solve_conic(sub, tol=tol, **options)


def solve_tresca_fixed_point(
    vi: MixedVI,
    tol: float = 1e-10,
    inner: str = "ssn",
    max_iter: int = 100,
    patience: int = 5,
    inner_tol: float | None = None,
    u0: np.ndarray | None = None,
    lam0: np.ndarray | None = None,
    **inner_options: Any,
) -> Solution:
    """Fixed point g ← tresca_bound(λ_n) on Tresca problems (module docstring).

    inner : the solver of each Tresca problem ("ssn", "homotopy" or "conic").
    max_iter : fixed-point iterations. patience : stop after this many steps in a row that did
        not shrink (diverging or cycling).
    inner_tol : relative residual asked of each Tresca solve (default tol / 10).
    u0, lam0 : initial guess (physical variables; λ0 in vi's row order).
    inner_options : passed to the inner solver unchanged (e.g. linear_solver).
    """
    if inner not in INNER:
        raise ValueError(f"inner solver {inner!r} unknown; allowed: {', '.join(INNER)}")
    t0 = time.perf_counter()
    seq = TrescaSequence(vi)
    s_n = vi.scaling.s_lam[seq.normal]  # (k_total,) equilibration of the normal multipliers
    inner_tol = tol / 10 if inner_tol is None else inner_tol
    u = np.zeros(vi.n) if u0 is None else np.asarray(u0, float)
    lam = np.zeros(vi.m) if lam0 is None else np.asarray(lam0, float)
    res = vi.residual(u, lam).relative
    history = [res]
    steps: list[float] = []
    rates: list[float] = []
    inner_iterations: list[int] = []
    warnings: list[str] = []
    converged, grew, j = res <= tol, 0, 0
    target = tol  # the tolerance of the current round (tightened while states are ambiguous)
    shortfall = 0.0
    rounds: list[dict] = []  # per round: its tolerance, residual and ambiguous nodes
    while True:
        while not converged and j < max_iter:
            j += 1
            sub = seq.problem(seq.bounds(lam))
            sol = _inner_solve(sub, inner, inner_tol, u, lam[seq.perm], dict(inner_options))
            inner_iterations.append(sol.iterations)
            if not sol.converged:
                warnings.append(
                    f"fixed_point: the Tresca problem of iteration {j} did not converge "
                    f"({inner}: residual {sol.residual:.3e})"
                )
                break
            lam_new = sol.lam[seq.inverse]
            steps.append(float(np.linalg.norm((lam_new[seq.normal] - lam[seq.normal]) / s_n)))
            if len(steps) > 1 and steps[-2] > 0:
                rates.append(steps[-1] / steps[-2])
                grew = grew + 1 if rates[-1] >= NO_CONTRACTION else 0
            # the last step's change of the bound: how far |λ_t| of a slipping node may lie
            # short of the bound at the new λ_n (the states' stress accuracy)
            shortfall = max(
                float(np.abs(a - b).max(initial=0.0))
                for a, b in zip(seq.bounds(lam_new), seq.bounds(lam), strict=True)
            )
            u, lam = sol.u, lam_new
            res = vi.residual(u, lam).relative
            history.append(res)
            converged = res <= target
            if not converged and grew >= patience:
                warnings.append(f"fixed_point: the step did not shrink {grew} times in a row")
                break
        # as ssn: return a multiplier in Λ(λ) exactly (the last Tresca answer satisfies the
        # bound of the previous λ_n); keep it only if the residual does not grow beyond target
        lam_feasible = vi.Lambda.project(lam)
        res_feasible = vi.residual(u, lam_feasible).relative
        if res_feasible <= max(res, target):
            lam, res = lam_feasible, res_feasible
            history[-1] = res
            converged = res <= target
        if not converged:
            break
        # confirm the partition (vi_core.states): a node whose evidence is ambiguous at this
        # residual (e.g. |λ_t| short of F λ_n by the last step while it slips) is settled by
        # more iterations at a tighter tolerance, at most TIGHTEN times
        labels = node_states.vi_states(vi, u, lam, res, lam_accuracy=shortfall)
        ambiguous = int(np.sum(labels == "ambiguous"))
        rounds.append({"tol": target, "residual": float(res), "ambiguous": ambiguous})
        if not ambiguous or len(rounds) > TIGHTEN or target / 10 < TIGHTEST:
            break
        target, inner_tol, converged, grew = target / 10, inner_tol / 10, False, 0
        kept = (u, lam, res, len(warnings), shortfall)
    if not converged and rounds:  # a tightening round failed: keep the confirmed answer
        u, lam, res, shortfall = (*kept[:3], kept[4])
        del warnings[kept[3] :]
        warnings.append(
            f"fixed_point: {rounds[-1]['ambiguous']} contact node(s) ambiguous at residual "
            f"{res:.3e}; tightening the tolerance to {target:.1e} did not converge"
        )
        converged = res <= tol
    elif converged and rounds[-1]["ambiguous"]:
        warnings.append(
            f"fixed_point: {rounds[-1]['ambiguous']} contact node(s) still ambiguous at "
            f"tolerance {target:.1e} (residual {res:.3e}, {len(rounds) - 1} tightening(s)): "
            "their states are reported ambiguous"
        )
    tail = rates[len(rates) // 2 :]
    if not converged:
        warnings.append(
            f"fixed_point: residual {res:.3e} did not reach tol {tol:.1e} in {j} iterations"
        )
    return Solution.of(
        "fixed_point",
        u,
        lam,
        res,
        converged,
        j,
        history,
        t0,
        info={
            "inner": inner,
            "inner_iterations": inner_iterations,
            "steps": steps,
            "rates": rates,
            "contraction": float(np.median(tail)) if tail else None,
            "states": {
                "rounds": rounds,
                "counts": node_states.counts(labels) if rounds else {},
                "lam_accuracy": shortfall,
            },
        },
        warnings=warnings,
    )
