"""Cross-solver battery: every applicable solver on gallery problems.

Counts (hypothesis, derandomised profile "ci"): see the `settings` of each test; the sum of
drawn problems over this file is ≥ 200 in the CI tier (274) and covers every set type and the
structures symmetric, skew-coupled and general with ρ ∈ [0.1, 3]. The three batteries that
solve with the homotopy (its oracle calls make them the slowest) draw fewer problems in the CI
tier; their `_full` twins in the slow tier (`-m slow`) draw the full counts (327 in all). The
homotopy at large ρ costs hundreds of oracle calls, so it runs on smaller problems than
semismooth Newton.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vi_core import constants, solve
from vi_core.testing import manufactured_strategy, vi_strategy

from .helpers import ACCEPT, AGREE, FAST, TOL, agree, applicable, record

N_SSN, N_CONIC, N_STABLE = 150, 40, 60
# (CI tier, slow tier) draws of the batteries that solve with the homotopy
N_HOMOTOPY, N_PAIRS, N_UNIQUE = (4, 12), (12, 40), (8, 25)


def tiers(counts: tuple[int, int], *strategies):
    """A battery `body` as two tests: `counts[0]` draws in the CI tier and `counts[1]` in the
    slow tier (the same derandomised draws first)."""

    def make(body):
        ci, full = counts
        draw = given(*strategies)
        return (
            settings(max_examples=ci)(draw(body)),
            pytest.mark.slow(settings(max_examples=full)(draw(body))),
        )

    return make


def _check_exact(mf, method, **options):
    record(mf.vi, mf.kind)
    sol = solve(mf.vi, method, tol=TOL, **FAST, **options)
    assert sol.converged, sol.warnings
    assert sol.residual <= ACCEPT
    assert mf.vi.residual(sol.u, sol.lam).relative <= ACCEPT  # the returned (u, λ) itself
    du, dlam = agree(mf.vi, sol, mf)
    assert du <= AGREE and dlam <= AGREE, (method, du, dlam)
    return sol


@settings(max_examples=N_SSN)
@given(manufactured_strategy(n_range=(6, 60), degenerate=(0.0, 0.5)))
def test_ssn_recovers_manufactured_solution(mf):
    _check_exact(mf, "ssn")


@settings(max_examples=N_CONIC)
@given(manufactured_strategy(structures=("symmetric", "skew-coupled"), n_range=(6, 40)))
def test_conic_recovers_manufactured_solution(mf):
    sol = _check_exact(mf, "conic")
    assert sol.info["status"] in ("optimal", "optimal_inaccurate")


def homotopy_recovers_manufactured_solution(mf):
    sol = _check_exact(mf, "homotopy", report_constants=False)
    assert sol.info["rate_bound"] <= 0.7


test_homotopy_recovers_manufactured_solution, test_homotopy_recovers_manufactured_solution_full = (
    tiers(N_HOMOTOPY, manufactured_strategy(n_range=(6, 20), degenerate=(0.0, 0.5)))(
        homotopy_recovers_manufactured_solution
    )
)


def solvers_agree_pairwise(vi):
    record(vi)
    sols = {m: solve(vi, m, tol=TOL, **FAST) for m in applicable(vi)}
    sols["auto"] = solve(vi, "auto", tol=TOL, **FAST)
    for m, s in sols.items():
        assert s.converged and s.residual <= ACCEPT, (m, s.residual, s.warnings)
    names = sorted(sols)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            du, dlam = agree(vi, sols[a], sols[b])
            assert du <= AGREE and dlam <= AGREE, (a, b, du, dlam)


test_solvers_agree_pairwise, test_solvers_agree_pairwise_full = tiers(
    N_PAIRS, vi_strategy(n_range=(6, 24), rho_range=(0.1, 2.0))
)(solvers_agree_pairwise)


def uniqueness_from_different_initial_guesses(vi, seed):
    """Theorem 3.1: one solution; two far-apart initial guesses must reach it."""
    record(vi)
    rng = np.random.default_rng(seed)
    u0 = 10.0 * rng.standard_normal(vi.n)
    lam0 = 10.0 * rng.standard_normal(vi.m)
    a = solve(vi, "ssn", tol=TOL, **FAST)
    b = solve(vi, "ssn", tol=TOL, u0=u0, lam0=lam0, **FAST)
    c = solve(vi, "homotopy", tol=TOL, u0=u0, lam0=lam0, report_constants=False, **FAST)
    for s in (a, b, c):
        assert s.converged and s.residual <= ACCEPT, s.warnings
    for s in (b, c):
        du, dlam = agree(vi, s, a)
        assert du <= AGREE and dlam <= AGREE, (s.method, du, dlam)


(
    test_uniqueness_from_different_initial_guesses,
    test_uniqueness_from_different_initial_guesses_full,
) = tiers(N_UNIQUE, vi_strategy(n_range=(6, 24), rho_range=(0.1, 2.0)), st.integers(0, 2**32 - 1))(
    uniqueness_from_different_initial_guesses
)


def _gram(rng, k):
    """A random SPD Gram matrix (a norm other than the Euclidean one)."""
    R = rng.standard_normal((k, k))
    return R @ R.T / k + np.diag(rng.uniform(0.5, 2.0, k))


@settings(max_examples=N_STABLE)
@given(
    vi_strategy(n_range=(6, 40)),
    st.integers(0, 2**32 - 1),
    st.floats(1e-3, 1e1),
    st.booleans(),
)
def test_stability_estimate_3_5(vi, seed, size, euclidean):
    """(3.9) ‖Δu‖_X ≤ ‖Δf‖_X'/m_a and (3.5) ‖Δu‖_X + ‖Δλ‖_Y ≤ C ‖Δf‖_X' with
    ‖Δf‖_X' = sqrt(Δfᵀ X^{-1} Δf), the X-norm of the Riesz representative of Δf."""
    record(vi)
    rng = np.random.default_rng(seed)
    X = None if euclidean else _gram(rng, vi.n)
    Y = None if euclidean else _gram(rng, vi.m)
    c = constants(vi, X=X, Y=Y)
    df = size * np.linalg.norm(vi.f) * rng.standard_normal(vi.n) / np.sqrt(vi.n)
    s1 = solve(vi, "ssn", tol=TOL, **FAST)
    s2 = solve(vi.with_rhs(f=vi.f + df), "ssn", tol=TOL, **FAST)
    assert s1.converged and s2.converged
    du, dlam, nf = c.norm_x(s1.u - s2.u), c.norm_y(s1.lam - s2.lam), c.dual_norm_x(df)
    assert du <= nf / c.m_a * (1 + 1e-8)
    assert du + dlam <= c.stability * nf * (1 + 1e-8)
