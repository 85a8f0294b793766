"""Nested iteration (`problems.pipeline`): the coarse levels solved to `coarse_tol`, the
fine level to the requested tolerance, and the answer that of a cold solve."""

from __future__ import annotations

import numpy as np

from problems import pipeline


def test_coarse_levels_stop_at_coarse_tol_and_the_fine_answer_is_the_cold_one():
    loaded = pipeline.load("paper_two_body")
    tol = 1e-10
    run = pipeline.solve(loaded, 3, tol=tol, linear_solver="amg")
    *coarse, fine = run.nested
    assert [r["tol"] for r in coarse] == [pipeline.coarse_tol(tol)] * 3 and fine["tol"] == tol
    assert all(r["converged"] and r["residual"] <= r["tol"] for r in run.nested)
    # the coarse levels did stop early (GMRES to the coarse tolerance): not a vacuous check
    assert max(r["residual"] for r in coarse[1:]) > 100 * tol
    assert run.solution.residual <= tol and fine["iterations"] == 1
    cold = pipeline.solve(loaded, 3, tol=tol, cold=True, linear_solver="splu").solution
    for a, b in ((run.solution.u, cold.u), (run.solution.lam, cold.lam)):
        assert np.linalg.norm(a - b) <= 1e-8 * np.linalg.norm(b)


def test_coarse_tol_never_tightens_the_requested_tolerance():
    assert pipeline.coarse_tol(1e-10) == pipeline.NESTED_TOL
    assert pipeline.coarse_tol(1e-3) == 1e-3  # a loose request is kept on every level
