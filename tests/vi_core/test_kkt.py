"""The independent KKT checker (vi_core.kkt): two implementations of one definition agree, the
checker sees exact solutions as exact, and it does not share the faults of the solvers' code."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import vi_core
import vi_core.sets as sets_module
from vi_core import Ball, Box, Free, MixedVI, NonNegative, product, solve
from vi_core.kkt import Checker
from vi_core.testing import manufactured_strategy, manufactured_vi, vi_strategy

from .helpers import FAST


@given(vi_strategy(spread=3.0), st.integers(0, 2**32 - 1))
def test_checker_equals_natural_residual_at_random_points(vi, seed):
    """Same definition, written twice: the two residuals agree to rounding at any point."""
    rng = np.random.default_rng(seed)
    scale_u = 1.0 / np.sqrt(vi.A.diagonal())
    u = rng.standard_normal(vi.n) * scale_u * 10.0 ** rng.uniform(-2, 2)
    lam = rng.standard_normal(vi.m) * 10.0 ** rng.uniform(-2, 2)
    mine = Checker.of(vi)(u, lam)
    theirs = vi.residual(u, lam)
    assert mine.relative == pytest.approx(theirs.relative, rel=1e-10, abs=1e-15)
    assert mine.equilibrium == pytest.approx(theirs.equilibrium, rel=1e-10, abs=1e-15)
    assert mine.projection == pytest.approx(theirs.complementarity, rel=1e-10, abs=1e-15)


@given(manufactured_strategy(spread=2.0))
def test_exact_solutions_are_exact_for_the_checker(mf):
    k = Checker.of(mf.vi)(mf.u, mf.lam)
    assert k.relative <= 1e-12
    assert k.complementarity <= 1e-12
    assert k.feasibility <= 1e-12


def _every_set_vi(seed: int = 3) -> MixedVI:
    rng = np.random.default_rng(seed)
    Lam = product(Free(2), Box(-1.0, 1.0, size=2), NonNegative(2), Ball([0.7, 0.4], 2))
    R = rng.standard_normal((12, 12))
    return MixedVI(
        A=R @ R.T + 12 * np.eye(12),
        B=rng.standard_normal((10, 12)),
        f=3 * rng.standard_normal(12),
        Lambda=Lam,
        gap=rng.standard_normal(10),
    )


def test_wrong_answers_are_seen():
    """A converged answer passes; the same answer with λ's sign flipped, or moved off Λ, fails."""
    vi = _every_set_vi()
    sol = solve(vi, "ssn", tol=1e-12, **FAST)
    check = Checker.of(vi)
    good = check(sol.u, sol.lam)
    assert good.relative <= 1e-12 and good.complementarity <= 1e-10
    bad = check(sol.u, -sol.lam)
    assert bad.relative > 1e-3 and bad.complementarity > 1e-3
    outside = check(sol.u, sol.lam * 3.0)
    assert outside.feasibility > 0.1


def test_checker_does_not_share_a_fault_in_the_sets_projection(monkeypatch):
    """Mutation: Box.project clips at 2·hi. The solvers' residual (natural_residual) and
    semismooth Newton inherit the fault and report convergence; the checker does not."""
    vi = _every_set_vi()
    orig = sets_module.Box.project

    def faulty(self, y):
        return np.clip(np.asarray(y, float), self.lo, 2.0 * self.hi)

    truth = solve(vi, "ssn", tol=1e-12, **FAST)
    monkeypatch.setattr(sets_module.Box, "project", faulty)
    wrong = solve(vi, "ssn", tol=1e-12, **FAST)
    assert wrong.converged and wrong.residual <= 1e-12  # the solver is fooled …
    assert np.abs(wrong.lam - truth.lam).max() > 1e-3
    assert Checker.of(vi)(wrong.u, wrong.lam).relative > 1e-4  # … the checker is not
    monkeypatch.setattr(sets_module.Box, "project", orig)


def test_checker_does_not_use_natural_residual(monkeypatch):
    """Mutation: natural_residual returns 0 for anything; the checker still sees a bad point."""
    vi = _every_set_vi()
    u, lam = np.zeros(vi.n), np.zeros(vi.m)
    truth = vi.residual(u, lam).relative
    zero = vi_core.Residual(0.0, 0.0, 1.0, 0.0)
    monkeypatch.setattr(vi_core.problem, "natural_residual", lambda *a, **k: zero)
    assert vi.residual(u, lam).relative == 0.0  # the fault is live …
    assert truth > 0.1
    assert Checker.of(vi)(u, lam).relative == pytest.approx(truth, rel=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_compare_allows_what_the_residuals_imply(seed):
    """Two answers at residual ~1e-6 differ by no more than `allowed`; a point moved by 10×
    what its residual permits is refused."""
    mf = manufactured_vi(seed, n=30, m=12, structure="skew-coupled", rho=1.0, spread=2.0)
    check = Checker.of(mf.vi)
    kappa = check.inverse_norm(mf.u, mf.lam)
    a = solve(mf.vi, "ssn", tol=1e-12, **FAST)
    b = solve(mf.vi, "homotopy", tol=1e-6, report_constants=False, **FAST)
    pair = check.compare((b.u, b.lam), (a.u, a.lam), kappa)
    assert 0 < max(pair["diff_u"], pair["diff_lam"]) <= pair["allowed"]
    # a perturbation far beyond what a tiny residual allows
    up, lp = check.scaled(a.u, a.lam)
    lp_bad = lp * (1 + 1e-4)
    moved = (a.u, lp_bad * check.s_lam)
    pair = check.compare(moved, (a.u, a.lam), kappa)
    assert pair["diff_lam"] > 0
    # the moved point's residual grows with the move, so allowed grows too: it must stay
    # below the move for a well-conditioned problem only if the residual is honest
    assert check(*moved).relative > 1e-7


def test_inverse_norm_of_an_identity_block():
    vi = MixedVI(A=np.eye(3), B=np.zeros((0, 3)), f=np.ones(3), Lambda=product())
    check = Checker.of(vi)
    assert check.inverse_norm(np.ones(3), np.zeros(0)) == pytest.approx(1.0)
