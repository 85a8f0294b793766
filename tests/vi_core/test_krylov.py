"""The iterative linear path (`vi_core.krylov`): agreement with the direct solver, the
reported residual, the fallbacks (stagnation, a factorisation over budget), the exact S rows
after GMRES, field data."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from vi_core import Box, MixedVI, block_amg, krylov, product, solve
from vi_core.tied_preconditioner import TiedPreconditioner

from .newton_systems import coupled_grid_vi, laplacian, lower_vi, newton_matrix

pytest.importorskip("pyamg")

seeds = st.integers(0, 2**32 - 1)


def _agree(vi: MixedVI, tol: float = 1e-10) -> tuple:
    """Solve with SuperLU and with amg; both must reach tol; return (difference, bound, amg)."""
    d = solve(vi, "ssn", tol=tol, linear_solver="splu", estimate_condition=True)
    a = solve(vi, "ssn", tol=tol, linear_solver="amg")
    assert d.converged and a.converged, (d.residual, a.residual)
    assert a.residual <= tol
    s = vi.scaling.s_u  # compare in equilibrated variables, where the condition is estimated
    diff = np.linalg.norm((a.u - d.u) / s) / np.linalg.norm(d.u / s)
    # forward error ≤ κ · residual for each, so they differ by at most 2κ·tol
    return diff, 2 * d.info["condition_estimate"] * tol, a


@given(seeds)
def test_amg_and_direct_agree_on_coupled_grids(seed):
    rng = np.random.default_rng(seed)
    vi = coupled_grid_vi(rng, int(rng.integers(8, 20)), float(rng.uniform(0.0, 2.0)))
    diff, bound, a = _agree(vi)
    assert diff <= bound
    assert a.info["linear_solver"] == "amg" and len(a.info["krylov_iterations"]) == a.iterations


def test_amg_reports_and_is_honest_about_the_residual():
    """The reported residual is the natural residual of the returned iterate."""
    vi = coupled_grid_vi(np.random.default_rng(3), 16, 1.0)
    a = solve(vi, "ssn", tol=1e-8, linear_solver="amg")
    assert a.converged
    assert a.residual == pytest.approx(vi.residual(a.u, a.lam).relative, rel=1e-6)
    assert a.info["fallback"] == []
    assert set(a.info["threads"]) >= {"OMP_NUM_THREADS", "MKL_NUM_THREADS", "cpu_count"}
    assert a.info["amg_fields"]["a"]["near_null_dim"] == 1


def test_unknown_linear_solver_is_refused():
    vi = coupled_grid_vi(np.random.default_rng(0), 6, 0.5)
    with pytest.raises(ValueError, match="amg"):
        solve(vi, "ssn", linear_solver="cg")


def test_not_condensable_falls_back_to_direct():
    """A dense random B has no private block: amg says so and solves directly."""
    rng = np.random.default_rng(1)
    n, m = 20, 5
    A = sp.csr_matrix(np.eye(n) * 3 + 0.1 * rng.standard_normal((n, n)))
    vi = MixedVI(A, rng.standard_normal((m, n)), rng.standard_normal(n), Box(-1.0, 1.0, size=m))
    a = solve(vi, "ssn", linear_solver="amg")
    assert a.converged and a.info["fallback"][0]["reason"].startswith("not condensable")


def test_stagnation_falls_back_to_the_direct_solver(monkeypatch):
    """A preconditioner that returns nothing on R: GMRES stalls, the step is redone directly,
    the fallback is reported, and the answer is still the direct one."""
    vi = coupled_grid_vi(np.random.default_rng(5), 14, 1.0)
    monkeypatch.setattr(block_amg.BlockAMG, "__call__", lambda self, r: np.zeros_like(r))
    diff, bound, a = _agree(vi)
    assert a.info["fallback"] and "stagnation" in a.info["fallback"][0]["reason"]
    assert diff <= bound


def test_field_data_is_checked_and_equilibrated():
    rng = np.random.default_rng(2)
    k = 6
    L = laplacian(k) * rng.uniform(1, 100)  # a unit change: scales differ from 1
    A = sp.block_diag([L, 50.0 * L]).tocsr()
    n1 = k * k
    N = rng.standard_normal((n1, 2))
    fields = {"a": np.arange(n1), "b": np.arange(n1, 2 * n1)}
    vi = MixedVI(A, sp.csr_matrix((0, 2 * n1)), np.ones(2 * n1), product(), fields=fields)
    vi = MixedVI(vi.A, vi.B, vi.f, vi.Lambda, fields=fields, near_null={"a": N})
    e = vi.equilibrated
    s = vi.scaling.s_u
    # A'N' = Su A N: the equilibrated near-null vectors are Su⁻¹ N
    a = fields["a"]
    lhs = e.A[a][:, a] @ e.near_null["a"]
    assert np.allclose(lhs, s[a][:, None] * (A[a][:, a] @ N), rtol=1e-12, atol=0)
    # the mutation: unscaled vectors would not satisfy it
    assert not np.allclose(e.A[a][:, a] @ N, s[a][:, None] * (A[a][:, a] @ N), rtol=1e-6)
    with pytest.raises(ValueError, match="overlaps"):
        MixedVI(A, vi.B, vi.f, product(), fields={"a": [0, 1], "b": [1, 2]})
    with pytest.raises(ValueError, match=r"near_null\['a'\]"):
        MixedVI(A, vi.B, vi.f, product(), fields=fields, near_null={"a": N[:-1]})
    with pytest.raises(ValueError, match="needs fields"):
        MixedVI(A, vi.B, vi.f, product(), near_null={"a": N})


@pytest.mark.parametrize("exact", [True, False])
def test_krylov_step_solves_the_s_rows_exactly(exact, monkeypatch):
    """An inexact step (η = 1e-6) still meets the S rows to rounding, so a slip row's multiplier
    λ = D^{-T}(f_S − A_S u) is on its bound as after a direct solve (nested iteration reads the
    stick/slip partition from it; paper scene level 5: 8 Newton steps instead of 2 without).
    Mutation (exact=False): without the exact S rows after GMRES they are off by about η."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(7)
    vi = lower_vi(rng, 40)  # 1,600 unknowns per field: hierarchies of more than one level
    cond = Condensation.detect(vi.B)
    tied = np.arange(vi.m) % 2 == 0
    K = newton_matrix(vi, cond, tied)
    b = rng.standard_normal(vi.n)
    ks = krylov.KrylovSolver(TiedPreconditioner(vi.A.tocsr(), vi.B, cond, vi.fields, None))
    if not exact:
        monkeypatch.setattr(krylov.KrylovSolver, "_exact_S_rows", lambda self, K, b, x: None)
    x, rec = ks(K, b, None, 1e-6, 1e-10, tied)
    assert rec["fallback"] is None and len(ks.preconditioner.amg.blocks[0].ml.levels) > 1
    assert np.linalg.norm(K @ x - b) <= 1e-6 * np.linalg.norm(b)
    s_rows = np.linalg.norm((K @ x - b)[cond.S]) / np.linalg.norm(b)
    assert (s_rows <= 1e-13) == exact, s_rows


def test_a_factorisation_over_budget_restarts_the_solve_with_amg(monkeypatch):
    """Injected: every SuperLU factorisation of the fine matrix is over budget. The solve ends
    on the iterative path and says so (info and a warning); the answer is the direct one."""
    from vi_core import linalg

    vi = coupled_grid_vi(np.random.default_rng(4), 14, 1.0)
    d = solve(vi, "ssn", tol=1e-10, linear_solver="splu", estimate_condition=True)
    n = vi.n

    real = linalg.superlu

    def over(At, ordering, budget):
        if At.shape[0] == n:
            raise MemoryError("injected over-fill")
        return real(At, ordering, budget)

    monkeypatch.setattr(linalg, "superlu", over)
    a = solve(vi, "ssn", tol=1e-10, linear_solver="splu")
    assert "solved with amg" in a.info["factorisation_fallback"]
    assert a.info["linear_solver"] == "amg" and a.converged
    assert any("over budget" in w for w in a.warnings)
    s = vi.scaling.s_u
    diff = np.linalg.norm((a.u - d.u) / s) / np.linalg.norm(d.u / s)
    assert diff <= 2 * d.info["condition_estimate"] * 1e-10


def test_a_solve_that_does_not_condense_cannot_fall_back_and_raises(monkeypatch):
    from vi_core import linalg

    vi = coupled_grid_vi(np.random.default_rng(4), 14, 1.0)
    monkeypatch.setattr(linalg, "superlu", lambda At, o, b: (_ for _ in ()).throw(MemoryError()))
    with pytest.raises(linalg.FactorizationTooLarge):
        solve(vi, "ssn", linear_solver="splu", condense=False)


def test_mutation_ssn_not_catching_the_overrun_fails_the_fallback_test(monkeypatch):
    import vi_core.ssn as ssn

    class Other(Exception):
        pass

    monkeypatch.setattr(ssn, "FactorizationTooLarge", Other)  # the handler no longer matches
    with pytest.raises(MemoryError):
        test_a_factorisation_over_budget_restarts_the_solve_with_amg(monkeypatch)
