"""What linear_solver="auto" chooses (`vi_core.linear_solvers`)."""

import numpy as np
import pytest

from vi_core import linear_solvers, solve
from vi_core.linear_solvers import AUTO_AMG_NNZ, auto_linear_solver

from .newton_systems import coupled_grid_vi

pytest.importorskip("pyamg")


def test_auto_chooses_direct_below_and_amg_above_the_size_of_its_kind(monkeypatch):
    assert auto_linear_solver(10_000, 1_000) == "auto"  # 10 per row: 2D, small
    assert auto_linear_solver(AUTO_AMG_NNZ[2] + 1, 100_000) == "amg"
    assert auto_linear_solver(AUTO_AMG_NNZ[2] + 1, 100_000, condensable=False) == "auto"
    # 3D (≥ ROW_3D entries per row) switches at its own, smaller size
    n3 = AUTO_AMG_NNZ[3] // 60 + 1
    assert auto_linear_solver(60 * n3, n3) == "amg"
    assert auto_linear_solver(20 * n3, n3) == "auto"  # the same entries, 2D
    vi = coupled_grid_vi(np.random.default_rng(2), 12, 1.0)
    small = solve(vi, "ssn", tol=1e-8)  # auto, small: direct
    assert small.info["linear_solver"] == "splu" and small.info["linear_solver_asked"] == "auto"
    monkeypatch.setattr(linear_solvers, "AUTO_AMG_NNZ", {2: 10, 3: 10})
    big = solve(vi, "ssn", tol=1e-8)
    assert big.info["linear_solver"] == "amg" and big.converged
