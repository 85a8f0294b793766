"""The dispatcher: method names, the "auto" rule and its fallback."""

import pytest

from vi_core import METHODS, solve
from vi_core.testing import random_vi

from .helpers import AGREE, FAST, TOL, agree


def test_methods():
    assert set(METHODS) == {"auto", "ssn", "conic", "homotopy"}
    with pytest.raises(ValueError, match="allowed: auto, ssn, conic, homotopy"):
        solve(random_vi(0), "newton")


@pytest.mark.parametrize("structure", ["symmetric", "skew-coupled", "general"])
def test_auto_takes_ssn(structure):
    vi = random_vi(1, n=20, m=8, structure=structure, rho=1.0)
    sol = solve(vi, tol=TOL, **FAST)
    assert sol.method == "ssn" and sol.info["auto"] == {"chosen": "ssn"} and sol.converged


@pytest.mark.parametrize(
    ("structure", "fallback"),
    [("symmetric", "conic"), ("skew-coupled", "conic"), ("general", "homotopy")],
)
def test_auto_falls_back_when_ssn_fails(structure, fallback):
    vi = random_vi(2, n=20, m=8, structure=structure, rho=1.0)
    sol = solve(vi, "auto", tol=TOL, max_iter=1, **FAST)  # one Newton step cannot make it
    assert sol.method == fallback and sol.info["auto"]["chosen"] == fallback
    assert sol.info["auto"]["ssn_residual"] > TOL
    assert sol.converged and sol.warnings[0].startswith("auto: ssn stopped")
    du, dlam = agree(vi, sol, solve(vi, "ssn", tol=TOL, **FAST))
    assert du <= AGREE and dlam <= AGREE
