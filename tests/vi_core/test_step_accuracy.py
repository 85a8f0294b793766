"""The accuracy the states read beyond the residual (`info["states"]["accuracy"]`,
`vi_core.states.solution_thresholds`) on the serial iterative path: the relative tolerance
GMRES was asked for at the last Newton step (`KrylovSolver.accuracy`), also where its guess
already met it and no GMRES iteration ran; the direct path records none (its thresholds read
the residual alone, unchanged)."""

from __future__ import annotations

from functools import cache

import pytest

import problems.pipeline as pipeline
from vi_core.ssn import solve_ssn


@cache
def hertz(linear_solver: str):
    run = pipeline.solve(pipeline.load("hertz"), 0, linear_solver=linear_solver)
    return run.model.vi, run.solution


def test_the_amg_path_records_the_asked_tolerance():
    vi, sol = hertz("amg")
    assert sol.info["krylov_iterations"][-1] > 0
    # never asked for more than 0.1·tol relative to ‖b‖ (`vi_core.forcing`), nor less than it
    # the last step of a converged run
    assert 0.1 * 1e-10 <= sol.info["states"]["accuracy"] < 1e-3


def test_a_step_without_gmres_iterations_records_its_tolerance():
    """From the answer with λ moved by 1e-8 (u exact: the step's linear residual is rounding),
    one Newton step whose GMRES takes no iteration: it was asked for 0.1·tol relative to ‖b‖
    (the forcing term's floor) and records that, not nothing."""
    vi, sol = hertz("amg")
    tol = 1e-13
    again = solve_ssn(vi, tol=tol, u0=sol.u, lam0=sol.lam * (1 + 1e-8), linear_solver="amg")
    assert again.info["krylov_iterations"] == [0] and again.converged
    assert again.info["states"]["accuracy"] == pytest.approx(0.1 * tol, rel=1e-12)


def test_the_direct_path_records_none():
    _, sol = hertz("splu")
    assert "states" not in sol.info
