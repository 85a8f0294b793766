"""The nested homotopy fixed point (Lemma 3.3): levels, contraction rates, oracles."""

import math

import numpy as np
import pytest

from vi_core import constants, solve
from vi_core.testing import manufactured_vi, random_vi

from .helpers import ACCEPT, AGREE, FAST, TOL, agree


@pytest.mark.parametrize("structure", ["skew-coupled", "general"])
@pytest.mark.parametrize("rho", [0.1, 0.5, 1.0, 2.0, pytest.param(3.0, marks=pytest.mark.slow)])
def test_levels_and_contraction(structure, rho):
    """L = ⌈ρ/t⌉ levels; every observed rate ‖Δ_{j+1}‖/‖Δ_j‖ (A_0 energy norm) ≤ (s − τ)ρ.
    CI: up to 3 levels (ρ = 2); ρ = 3 (5 levels, half the file's CPU) in the slow tier."""
    mf = manufactured_vi(11, n=24, m=10, structure=structure, rho=rho, degenerate=0.2)
    sol = solve(mf.vi, "homotopy", tol=TOL, rate=0.7, report_constants=False, **FAST)
    assert sol.converged and sol.residual <= ACCEPT
    du, dlam = agree(mf.vi, sol, mf)
    assert du <= AGREE and dlam <= AGREE
    info = sol.info
    assert info["rho"] == pytest.approx(rho, rel=1e-8)
    n_levels = len(info["levels"]) - 1
    assert n_levels == math.ceil(info["rho"] / 0.7)
    assert info["rate_bound"] == pytest.approx(info["rho"] / n_levels)
    for level in info["per_level"][1:]:
        assert level["rate_max"] <= info["rate_bound"] * (1 + 1e-6), level
    # nesting: each level is called by the one above, at least once per iteration above
    per = info["per_level"]
    for lower, upper in zip(per[:-1], per[1:], strict=True):
        assert lower["calls"] == upper["iterations"]


def test_symmetric_needs_one_oracle_call():
    mf = manufactured_vi(2, n=30, m=12, structure="symmetric")
    sol = solve(mf.vi, "homotopy", tol=TOL, report_constants=False, **FAST)
    assert sol.converged and sol.info["rho"] == 0.0
    assert sol.info["oracle_calls"] == 1 and sol.iterations == 1
    du, dlam = agree(mf.vi, sol, mf)
    assert du <= AGREE and dlam <= AGREE


@pytest.mark.parametrize("seed", range(3))
def test_conic_oracle_agrees_with_ssn_oracle(seed):
    vi = random_vi(seed, n=16, m=6, structure="general", rho=0.6)
    a = solve(vi, "homotopy", tol=TOL, inner="conic", report_constants=False, **FAST)
    b = solve(vi, "homotopy", tol=TOL, inner="ssn", report_constants=False, **FAST)
    assert a.converged and b.converged and a.residual <= ACCEPT
    assert a.info["inner"] == "conic"
    du, dlam = agree(vi, a, b)
    assert du <= AGREE and dlam <= AGREE


def test_reports_the_paper_bound():
    vi = random_vi(5, n=20, m=8, structure="general", rho=1.2)
    sol = solve(vi, "homotopy", tol=TOL, **FAST)
    c = constants(vi)
    assert sol.info["t0_paper"] == pytest.approx(c.t0)
    assert sol.info["m_a"] == pytest.approx(c.m_a) and sol.info["alpha"] == pytest.approx(c.alpha)
    history = np.array(sol.history)
    assert history[-1] == sol.residual and len(history) == sol.iterations + 1


def test_rejects_bad_options():
    vi = random_vi(0, n=10, m=5, structure="general")
    with pytest.raises(ValueError, match="inner oracle"):
        solve(vi, "homotopy", inner="newton")
    with pytest.raises(ValueError, match="rate"):
        solve(vi, "homotopy", rate=1.0)


def test_refuses_too_many_levels():
    vi = random_vi(4, n=12, m=5, structure="general", rho=3.0)
    sol = solve(vi, "homotopy", tol=TOL, max_levels=2, report_constants=False, **FAST)
    assert not sol.converged and sol.iterations == 0
    assert sol.info["levels_needed"] == 5 and "max_levels = 2" in sol.warnings[0]
