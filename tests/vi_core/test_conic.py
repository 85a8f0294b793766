"""The conic path: dual sign, skew-coupled QP, status mapping, settings, polishing."""

import numpy as np
import pytest

from vi_core import Box, Free, MixedVI, NonNegative, product, solve
from vi_core.testing import manufactured_vi, random_vi

from .helpers import ACCEPT, AGREE, FAST, TOL, agree


@pytest.mark.parametrize(
    ("Lambda", "gap", "u1", "lam"),
    [
        (Box(-0.5, 0.5), 0.0, 1.5, 0.5),  # u1 = 2 − λ, |λ| ≤ 0.5 active at +0.5
        (NonNegative(1), 1.0, 1.0, 1.0),  # u1 ≤ 1: λ = 2 − 1 = 1
        (Free(1), -0.5, -0.5, 2.5),  # u1 = −0.5: λ = 2 + 0.5
    ],
)
def test_dual_sign(Lambda, gap, u1, lam):
    """λ is +1 × cvxpy's dual of `B @ u - gap == z` (hand-solved 2-unknown problems)."""
    vi = MixedVI(A=np.eye(2), B=[[1.0, 0.0]], f=[2.0, 1.0], Lambda=Lambda, gap=[gap])
    sol = solve(vi, "conic", tol=1e-7, polish=0)
    assert sol.converged and "polish" not in sol.info
    np.testing.assert_allclose(sol.u, [u1, 1.0], atol=1e-7)
    np.testing.assert_allclose(sol.lam, [lam], atol=1e-7)


@pytest.mark.parametrize("seed", range(4))
def test_skew_coupled_qp_solves_the_nonsymmetric_vi(seed):
    mf = manufactured_vi(seed, n=30, m=10, structure="skew-coupled", rho=2.5, spread=2.0)
    assert mf.vi.structure == "skew-coupled"
    sol = solve(mf.vi, "conic", tol=TOL, **FAST)
    assert sol.converged and sol.residual <= ACCEPT
    du, dlam = agree(mf.vi, sol, mf)
    assert du <= AGREE and dlam <= AGREE


def test_general_nonsymmetric_is_refused():
    vi = random_vi(0, n=12, m=5, structure="general", rho=0.5)
    with pytest.raises(ValueError, match='method="homotopy"'):
        solve(vi, "conic")


def test_clarabel_settings_pass_through():
    vi = random_vi(1, n=20, m=8, structure="symmetric")
    sol = solve(vi, "conic", tol=TOL, clarabel={"max_iter": 2}, polish=0)
    assert sol.info["clarabel"]["max_iter"] == 2
    assert sol.info["ipm_iterations"] <= 2
    assert not sol.converged and sol.warnings


def test_infeasible_is_not_converged():
    """Free multipliers with B u = gap inconsistent (two equal rows, different gaps)."""
    vi = MixedVI(
        A=np.eye(2), B=[[1.0, 0.0], [1.0, 0.0]], f=[1.0, 1.0], Lambda=Free(2), gap=[0.0, 1.0]
    )
    sol = solve(vi, "conic", tol=TOL)
    assert not sol.converged
    assert "infeasible" in sol.info["status"]
    assert any("status" in w for w in sol.warnings)


def test_polishing_is_reported_honestly():
    mf = manufactured_vi(0, n=30, m=12, structure="symmetric", spread=2.0)
    raw = solve(mf.vi, "conic", tol=1e-13, polish=0)
    pol = solve(mf.vi, "conic", tol=1e-13, polish=3, **FAST)
    before = raw.info["conic_residual"]
    assert raw.converged == (before <= 1e-13)
    if before > 1e-13:
        p = pol.info["polish"]
        assert p["residual_before"] == pytest.approx(before)
        assert p["residual_after"] < before and 1 <= p["steps"] <= 3
        assert p["relative_change"] > 0
        assert pol.iterations == 1 + p["steps"]
    assert pol.residual <= before


def test_every_set_type_in_one_problem():
    Lam = product(Free(2), Box(-1.0, 1.0, size=2), NonNegative(2))
    rng = np.random.default_rng(4)
    R = rng.standard_normal((8, 8))
    vi = MixedVI(
        A=R @ R.T + 8 * np.eye(8),
        B=rng.standard_normal((6, 8)),
        f=rng.standard_normal(8),
        Lambda=Lam,
        gap=rng.standard_normal(6),
    )
    a, b = solve(vi, "conic", tol=TOL, **FAST), solve(vi, "ssn", tol=TOL, **FAST)
    assert a.converged and b.converged
    du, dlam = agree(vi, a, b)
    assert du <= AGREE and dlam <= AGREE


def _scaled(vi: MixedVI, factor: float) -> MixedVI:
    """The same VI with f, gap and the bounds of Λ multiplied by `factor`."""
    return MixedVI(
        A=vi.A,
        B=vi.B,
        f=vi.f * factor,
        Lambda=vi.Lambda.scaled(np.full(vi.m, 1.0 / factor)),
        gap=vi.gap * factor,
    )


@pytest.mark.parametrize("seed", range(3))
def test_scale_invariance(seed):
    """Data and bounds × 1e-12 … 1e12: the raw conic answer has the same relative residual and
    scales with the data (the VI is positively homogeneous of degree 1). On a scene:
    tests/problems/commands/test_check.py::test_conic_scale_invariance_on_a_scene."""
    mf = manufactured_vi(
        seed, n=24, m=10, structure="skew-coupled", rho=0.8, spread=1.0, degenerate=0.0
    )
    base = solve(mf.vi, "conic", tol=TOL, polish=0)
    assert base.info["status"] == "optimal"
    for factor in (1e-12, 1e-6, 1e6, 1e12):
        sol = solve(_scaled(mf.vi, factor), "conic", tol=TOL, polish=0)
        assert sol.info["status"] == "optimal", factor
        # as accurate at every scale: within one order of magnitude of the unscaled residual
        # (not equal to 1 %: the normalised data differ from the unscaled by rounding, and the
        # interior-point iterates' last digits follow it — 2.7e-8 unscaled, 4.6e-9 at 1e12 with
        # Clarabel 0.11.1 here; the mutation below, no normalisation, gives > 1e-3)
        assert sol.residual <= 10 * max(base.residual, TOL), factor
        np.testing.assert_allclose(sol.u / factor, base.u, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(sol.lam / factor, base.lam, rtol=1e-6, atol=1e-9)


def test_scale_invariance_fails_without_normalisation(monkeypatch):
    """Mutation: without the normalisation, data × 1e-12 break the raw conic answer."""
    import vi_core.conic as conic

    mf = manufactured_vi(
        0, n=24, m=10, structure="skew-coupled", rho=0.8, spread=1.0, degenerate=0.0
    )
    vi = _scaled(mf.vi, 1e-12)
    assert solve(vi, "conic", tol=TOL, polish=0).residual <= 1e-9
    monkeypatch.setattr(conic, "_normalisation", lambda e: 1.0)
    assert solve(vi, "conic", tol=TOL, polish=0).residual > 1e-3
