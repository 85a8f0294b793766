"""An iterative linear path for the semismooth Newton steps: GMRES with algebraic multigrid.

`KrylovSolver` solves the condensed Newton systems K u = b of one ssn run
(`vi_core.condensed_newton`) by restarted GMRES (`vi_core.gmres`) with the tied-rows
preconditioner (`vi_core.tied_preconditioner`: the tied contact rows eliminated exactly, one
multigrid cycle per field for the rest), each step to the tolerance of its forcing term
(`vi_core.forcing`). Which linear solver a solve uses: `vi_core.linear_solvers`.

After GMRES the S rows are solved exactly once more (K_SS by SuperLU): a slip row's
multiplier is then on its bound to rounding, as after a direct solve — nested iteration reads
the stick/slip partition of the coarse answer, and without it the paper scene's level 5 took 8
Newton steps instead of 2.

**Fallback.** A solve whose true residual falls by less than a factor 0.9 over a restart cycle,
or does not reach its tolerance within `max_cycles` cycles, is redone by the direct solver; the
step and the reason are recorded in `info["fallback"]`.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .condensed_newton import CondensedNewton
from .gmres import gmres_cycle
from .tied_preconditioner import Spring, TiedPreconditioner


class KrylovSolver:
    """Solves the condensed Newton systems K u = b of one ssn run (module docstring).

    preconditioner : the tied-rows preconditioner of the run's equilibrated operator and
        constraint rows (`TiedPreconditioner`, which takes the problem's data).
    restart, max_cycles : GMRES(restart), at most `max_cycles` restart cycles before the
        direct fallback.
    """

    def __init__(self, preconditioner: TiedPreconditioner, restart: int = 50, max_cycles: int = 8):
        self.preconditioner = preconditioner
        self.S = self.preconditioner.S  # (m,) the slave columns
        self.n = self.preconditioner.n
        self.restart, self.max_cycles = restart, max_cycles
        self.steps: list[dict] = []  # per Newton step: iterations, tolerance, residual, …
        self.time = 0.0
        self.on_iteration: Callable[[int], None] | None = None  # after each GMRES iteration,
        # with the iterations of the current solve so far (`ssn.solve_ssn`'s on_step)

    def __call__(
        self,
        K: sp.csr_matrix | CondensedNewton,
        b: np.ndarray,
        x0: np.ndarray | None,
        eta: float,
        tol: float,
        tied: np.ndarray,
        W: sp.spmatrix | None = None,
        J: sp.spmatrix | None = None,
    ) -> tuple[np.ndarray | None, dict]:
        """Solve K x = b to ‖b − Kx‖ ≤ max(η‖b − K x0‖, 0.1·tol·‖b‖); tied (m,) the rows whose
        W row is zero (a tying condition (B u)_i = …; the others are stiffness rows); W, J (m, m)
        the step's matrices, where given the free rows with J ≠ 0 (3D slip discs) are springs
        in the preconditioner (module docstring); without them such rows count as J = 0.

        Returns (x, record); x is None where the solve stagnated (record["fallback"] says why).
        """
        from threadpoolctl import threadpool_limits

        # the BLAS calls of set-up and Krylov vectors are far too small to gain from threads: on
        # the shared 2-core machine OpenBLAS's threads made the paper scene's level 3 solve 8×
        # slower (set-up 8.1 s → 0.3 s, GMRES 5.9 s → 1.2 s with one thread)
        with threadpool_limits(limits=1, user_api="blas"):
            tied = np.asarray(tied, dtype=bool)
            return self._solve(K, b, x0, eta, tol, tied, Spring.of(tied, W, J))

    def _exact_S_rows(self, K: sp.csr_matrix, b: np.ndarray, x: np.ndarray) -> None:
        """x_S += K_SS⁻¹ (b − K x)_S in place: the S rows solved exactly (one block Gauss–Seidel
        step; a slip row's multiplier is then on its bound to rounding, module docstring)."""
        S = self.S
        K_S = K.K_S if isinstance(K, CondensedNewton) else K[S]  # (m, n)
        x[S] += spla.splu(sp.csc_matrix(K_S[:, S])).solve((b - K @ x)[S])

    def _solve(self, K, b, x0, eta, tol, tied, spring=None):
        t0 = time.perf_counter()
        M = self.preconditioner(tied, spring)
        x = np.zeros(self.n) if x0 is None else np.array(x0, dtype=float)
        nb = float(np.linalg.norm(b))
        r0 = float(np.linalg.norm(b - K @ x))
        target = max(eta * r0, 0.1 * tol * nb)
        its = [0]

        def count(_):
            its[0] += 1
            if self.on_iteration is not None:
                self.on_iteration(its[0])

        record = {"eta": eta, "target": target / nb if nb else 0.0, "fallback": None}
        res, cycles = r0, 0
        while res > target:
            if cycles == self.max_cycles:
                record["fallback"] = f"no convergence in {cycles} GMRES({self.restart}) cycles"
                break
            with warnings.catch_warnings():  # a (near) breakdown is judged by the residual below
                warnings.simplefilter("ignore", sla.LinAlgWarning)
                x, _ = gmres_cycle(K, b, x, M, target, min(self.restart, self.n), count)
            cycles += 1
            new = float(np.linalg.norm(b - K @ x))
            if new > 0.9 * res and new > target:
                record["fallback"] = f"stagnation: residual {res:.2e} → {new:.2e} in a cycle"
                res = new
                break
            res = new
        if record["fallback"] is None and res > 0:
            self._exact_S_rows(K, b, x)
            res = float(np.linalg.norm(b - K @ x))
        record.update(iterations=its[0], residual=res / nb if nb else 0.0)
        self.time += time.perf_counter() - t0
        self.steps.append(record)
        return (None if record["fallback"] else x), record

    def accuracy(self) -> float | None:
        """The relative accuracy of the last step beyond what its residual shows: the relative
        tolerance GMRES was asked for (its target ‖b − K x‖ / ‖b‖, the forcing term's), also
        where the guess already met it and no iteration ran; 0 where the step fell back to
        the direct solver (exact to rounding); None before any step. The states' thresholds
        read it (`vi_core.states.solution_thresholds`)."""
        if not self.steps:
            return None
        last = self.steps[-1]
        return 0.0 if last["fallback"] else float(last["target"])

    def info(self) -> dict:
        """What the Newton solve's `info` reports about the iterative path."""
        pre = self.preconditioner
        return {
            "krylov": "gmres (vi_core.gmres, right preconditioned)",
            "restart": self.restart,
            "preconditioner": (
                f"tied rows eliminated, smoothed aggregation per field ({pre.cycle}-cycle)"
            ),
            "krylov_iterations": [s["iterations"] for s in self.steps],
            "krylov_residuals": [s["residual"] for s in self.steps],
            "forcing_terms": [s["eta"] for s in self.steps],
            "fallback": [
                {"step": i + 1, "reason": s["fallback"]}
                for i, s in enumerate(self.steps)
                if s["fallback"]
            ],
            "amg_setups": len(pre.setups),
            "amg_setup_s": float(sum(pre.setups)),
            "amg_fields": pre.amg.describe() if pre.amg else {},
            "linear_time_s": self.time,
        }
