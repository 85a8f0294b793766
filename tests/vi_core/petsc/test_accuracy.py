"""The accuracy the petsc engine's amg path records for the states (`LinearSolve.accuracy`,
`info["states"]["accuracy"]`): the rtol GMRES was asked for at the last Newton step, the one
``-mixvi_ksp_rtol`` sets where given (not the default's 1e-12 whatever was asked), also for a
step whose GMRES took no iteration. One process, in this one (COMM_WORLD of one rank)."""

from __future__ import annotations

from functools import cache

import pytest

import problems.pipeline as pipeline

from .helpers import need_petsc

pytestmark = pytest.mark.mpi


@cache
def hertz():
    run = pipeline.solve(pipeline.load("hertz"), 0, linear_solver="splu")
    return run.model.vi, run.solution


@pytest.mark.parametrize("rtol", [None, 1e-9])
def test_the_asked_rtol_is_recorded(rtol):
    need_petsc()
    from vi_core.petsc import solve_ssn_petsc
    from vi_core.petsc.ksp import GMRES_RTOL
    from vi_core.petsc.runtime import petsc

    opts = petsc().Options()
    if rtol is not None:
        opts.setValue("mixvi_ksp_rtol", rtol)
    try:
        vi, sol = hertz()
        cold = solve_ssn_petsc(vi, linear_solver="amg")
        # from the answer with λ moved by 1e-8 (u exact): one step, GMRES's guess within rtol
        warm = solve_ssn_petsc(
            vi, tol=1e-13, u0=sol.u, lam0=sol.lam * (1 + 1e-8), linear_solver="amg"
        )
    finally:
        if rtol is not None:
            opts.delValue("mixvi_ksp_rtol")
    asked = GMRES_RTOL if rtol is None else rtol
    assert cold.converged and cold.info["krylov_iterations"][-1] > 0
    assert cold.info["states"]["accuracy"] == asked
    assert warm.info["krylov_iterations"] == [0]
    assert warm.info["states"]["accuracy"] == asked
