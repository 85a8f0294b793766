"""Coulomb friction as a quasi-variational inequality (vi_core.coulomb, vi_core.tresca_fixed_point):
the combined map and its derivative, the two solution paths against each other and against
limits with independent references, the independent checker (vi_core.kkt), and mutations that
each check must catch."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import vi_core.coulomb as coulomb_module
from vi_core import (
    Ball,
    Box,
    Coulomb,
    Free,
    MixedVI,
    NonNegative,
    UnilateralTresca,
    product,
    solve,
)
from vi_core.kkt import Checker
from vi_core.testing import STRUCTURES, random_contact_vi
from vi_core.tresca_fixed_point import TrescaSequence

from .helpers import ACCEPT, AGREE, FAST, TOL, agree

F_CONVERGES = 0.5  # measured: every draw below converges on both paths (docs/coulomb.md)


def _rows(vi: MixedVI, dim: int, free: int) -> tuple[np.ndarray, np.ndarray]:
    """(normal rows (k,), tangential rows (k·(dim−1),)) of a contact block after `free` rows."""
    rows = np.arange(free, vi.m).reshape(-1, dim)
    return rows[:, 0], rows[:, 1:].ravel()


def _derivative_error(S, y: np.ndarray, rng: np.random.Generator) -> float:
    """max |J d − (P(y + εd) − P(y − εd)) / 2ε| / |d| over random directions d (central
    differences; y away from kinks, so P is affine-free smooth there)."""
    J = S.jacobian(y)
    worst = 0.0
    for _ in range(5):
        d = rng.standard_normal(y.size)
        eps = 1e-7
        fd = (S.project(y + eps * d) - S.project(y - eps * d)) / (2 * eps)
        worst = max(worst, float(np.abs(J @ d - fd).max() / np.abs(d).max()))
    return worst


def _smooth_point(S, rng: np.random.Generator) -> np.ndarray:
    """A random y with every node at least 0.1 from the kinks y_n = 0 and |y_t| = ρ(y_n)."""
    Y = rng.standard_normal((S.k, S.dim)) * 2.0
    Y[:, 0] = np.where(np.abs(Y[:, 0]) < 0.1, 0.5, Y[:, 0])
    r, _ = S.radius(Y[:, 0])
    nt = np.linalg.norm(Y[:, 1:], axis=1)
    near = np.abs(nt - r) < 0.1
    Y[near, 1:] *= 1.5 + 0.2 / np.maximum(nt[near, None], 1e-3)
    return Y.ravel()


SETS = {
    "coulomb": lambda rng, dim: Coulomb(rng.uniform(0.0, 2.0, 6), dim),
    "tresca_contact": lambda rng, dim: UnilateralTresca(rng.uniform(0.1, 2.0, 6), dim),
    "tresca": lambda rng, dim: UnilateralTresca(rng.uniform(0.1, 2.0, 6), dim, False),
}


@given(st.integers(0, 2**32 - 1), st.sampled_from(sorted(SETS)), st.sampled_from((2, 3)))
def test_jacobian_is_the_derivative_of_the_combined_map(seed, kind, dim):
    rng = np.random.default_rng(seed)
    S = SETS[kind](rng, dim)
    assert _derivative_error(S, _smooth_point(S, rng), rng) <= 1e-6


NEWTON_STEPS = 10  # measured 2–6 Newton steps on these gallery problems (F = 0.5); 16–51 with
# the slip row's sign flipped (the answers stay right: only the Jacobian is wrong)


def _newton_steps() -> list[int]:
    steps = []
    for seed in range(3):
        for dim in (2, 3):
            vi = random_contact_vi(seed, n=40, k=8, dim=dim, F=0.5, structure="general",
                                   free=2, rho=1.0)  # fmt: skip
            sol = solve(vi, "ssn", tol=TOL, **FAST)
            assert sol.converged
            steps.append(sol.iterations)
    return steps


def test_newton_converges_fast():
    assert max(_newton_steps()) <= NEWTON_STEPS


def test_mutation_sign_of_the_tangential_derivative_is_caught(monkeypatch):
    """Mutation: dρ/dy_n with the wrong sign (the slip row −F ŷ instead of F ŷ). The derivative
    check catches it, and so does the Newton step count (superlinear convergence is lost)."""
    rng = np.random.default_rng(7)
    S = Coulomb(rng.uniform(0.5, 2.0, 6), 2)
    y = _smooth_point(S, rng)
    Y = y.reshape(6, 2)
    Y[:, 0], Y[:, 1] = 1.0, 5.0  # every node in contact and slipping: the slip row matters
    y = Y.ravel()
    assert _derivative_error(S, y, rng) <= 1e-6
    orig = Coulomb.radius
    monkeypatch.setattr(Coulomb, "radius", lambda self, yn: (orig(self, yn)[0], -orig(self, yn)[1]))
    assert _derivative_error(S, y, rng) > 0.1
    assert max(_newton_steps()) > NEWTON_STEPS


def test_combined_map_is_the_identity_on_the_set_and_lands_in_it():
    rng = np.random.default_rng(0)
    S = Coulomb(rng.uniform(0.0, 1.0, 50), 3)
    Y = rng.standard_normal((50, 3))
    Y[:, 0] = np.abs(Y[:, 0])
    Y[:, 1:] *= (S.F * Y[:, 0] / np.maximum(np.linalg.norm(Y[:, 1:], axis=1), 1e-300))[:, None]
    Y[:, 1:] *= rng.uniform(0, 1, (50, 1))  # inside the cone |λ_t| ≤ F λ_n
    assert np.array_equal(S.project(Y.ravel()), Y.ravel())
    P = S.project(3 * rng.standard_normal(150)).reshape(50, 3)
    assert (P[:, 0] >= 0).all()
    assert (np.linalg.norm(P[:, 1:], axis=1) <= S.F * P[:, 0] * (1 + 1e-14)).all()


def test_bad_data_is_refused():
    with pytest.raises(ValueError, match="F must be finite and ≥ 0; node 1"):
        Coulomb([0.1, -0.2])
    with pytest.raises(ValueError, match="dim 2 or 3"):
        Coulomb(0.1, dim=4)
    with pytest.raises(ValueError, match="g must be finite and ≥ 0"):
        UnilateralTresca([np.inf])
    with pytest.raises(ValueError, match="uniformly within each node"):
        Coulomb([0.1, 0.2]).scaled(np.array([1.0, 2.0, 1.0, 1.0]))


# --------------------------------------------------------------------- both paths agree
def _both(vi: MixedVI, inner: str = "ssn"):
    opts = {} if inner == "conic" else FAST
    newton = solve(vi, "ssn", tol=TOL, **FAST)
    fixed = solve(vi, "fixed_point", tol=TOL, inner=inner, **opts)
    return newton, fixed


def _judged(vi: MixedVI, sol) -> None:
    """The independent checker's verdict on a converged answer."""
    check = Checker.of(vi)
    k = check(sol.u, sol.lam)
    assert k.relative <= ACCEPT and k.complementarity <= 1e-8 and k.feasibility <= 1e-12
    assert check.contact(sol.u, sol.lam).worst <= 1e-8


@settings(max_examples=40)
@given(
    st.integers(0, 2**32 - 1),
    st.sampled_from((2, 3)),
    st.sampled_from(STRUCTURES),
    st.integers(0, 10),
    st.sampled_from((0.0, 2.0)),
)
def test_newton_and_fixed_point_agree_on_random_problems(seed, dim, structure, f10, spread):
    """A non-symmetric A with A + Aᵀ > 0, 2 free rows and 4 contact nodes; F on a 0.05 grid in
    [0, F_CONVERGES]: both paths converge, the checker accepts both, and they agree within the
    difference their residuals allow."""
    F = f10 * F_CONVERGES / 10
    vi = random_contact_vi(seed, n=24, k=4, dim=dim, F=F, structure=structure, free=2,
                           rho=1.0, spread=spread)  # fmt: skip
    newton, fixed = _both(vi)
    assert newton.converged and fixed.converged
    for sol in (newton, fixed):
        _judged(vi, sol)
    check = Checker.of(vi)
    cmp = check.compare((fixed.u, fixed.lam), (newton.u, newton.lam),
                        check.inverse_norm(newton.u, newton.lam))  # fmt: skip
    assert cmp["diff_u"] <= max(cmp["allowed"], 1e-12)
    assert cmp["diff_lam"] <= max(cmp["allowed"], 1e-12)
    if F > 0 and fixed.info["contraction"] is not None:
        assert 0 <= fixed.info["contraction"] < 1


@pytest.mark.parametrize(
    ("inner", "structure"),
    [(inner, s) for inner in ("homotopy", "conic") for s in STRUCTURES][
        :-1
    ],  # the conic path needs a symmetric or skew-coupled A: no (conic, general)
)
def test_every_inner_solver_gives_the_newton_answer(inner, structure):
    vi = random_contact_vi(3, n=24, k=4, dim=3, F=0.4, structure=structure, free=2, rho=0.5)
    newton, fixed = _both(vi, inner)
    assert newton.converged and fixed.converged and fixed.info["inner"] == inner
    _judged(vi, fixed)
    du, dl = agree(vi, fixed, newton)
    assert du <= AGREE and dl <= AGREE


# ------------------------------------------------------------------------------ limits
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(4))
def test_zero_friction_is_the_frictionless_problem(seed, dim):
    """F = 0 is exactly frictionless unilateral contact: the reference keeps the free and
    normal rows only (Λ = Free × NonNegative, a convex VI). F = 1e-8 is within 1e-6 of it."""
    vi = random_contact_vi(seed, n=24, k=4, dim=dim, F=0.0, structure="general", free=2)
    normal, tangential = _rows(vi, dim, 2)
    keep = np.concatenate([np.arange(2), normal])
    ref_vi = MixedVI(A=vi.A, B=vi.B[keep], f=vi.f, gap=vi.gap[keep],
                     Lambda=product(Free(2), NonNegative(normal.size)))  # fmt: skip
    ref = solve(ref_vi, "ssn", tol=1e-12, **FAST)
    assert ref.converged and (ref.lam[2:] > 0).any()
    for F, close in ((0.0, 1e-10), (1e-8, 1e-6)):
        vi_F = random_contact_vi(seed, n=24, k=4, dim=dim, F=F, structure="general", free=2)
        for sol in _both(vi_F):
            assert sol.converged
            assert np.abs(sol.u - ref.u).max() <= close * np.abs(ref.u).max()
            assert np.abs(sol.lam[keep] - ref.lam).max() <= close * np.abs(ref.lam).max()
            assert np.abs(sol.lam[tangential]).max() <= close * np.abs(ref.lam).max()


def _decoupled(seed: int, dim: int, F: float, structure: str = "general") -> MixedVI:
    return random_contact_vi(seed, n=30, k=4, dim=dim, F=F, structure=structure,
                             free=1, decoupled=True)  # fmt: skip


def _tresca_reference(vi: MixedVI, dim: int, g: np.ndarray | None, method: str = "conic"):
    """The convex VI with the tangential rows under Box/Ball(g) (or Free, g None) on the nodes
    in contact in `g`'s support, λ_t = 0 elsewhere; normal rows as they are."""
    normal, tangential = _rows(vi, dim, 1)
    order = np.concatenate([np.arange(1), normal, tangential])
    k = normal.size
    if g is None:
        tang: list = [Free(tangential.size)]
    else:
        tang = [Box(-g, g)] if dim == 2 else [Ball(g, dim - 1)]
    Lam = product(Free(1), NonNegative(k), *tang)
    ref_vi = MixedVI(A=vi.A, B=vi.B[order], f=vi.f, gap=vi.gap[order], Lambda=Lam)
    ref = solve(ref_vi, method, tol=1e-12, **({} if method == "conic" else FAST))
    lam = np.empty(vi.m)
    lam[order] = ref.lam
    return ref, lam


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(3))
def test_known_pressure_reduces_coulomb_exactly_to_tresca(seed, dim):
    """Decoupled problem (λ_n independent of friction, like a strip under uniform pressure):
    Coulomb equals the Tresca problem with g = F λ_n, λ_n from the frictionless solve, the
    Tresca problem solved on the conic path; the fixed point needs exactly two Tresca solves
    (g = 0, then g = F λ_n) and its second step is its last."""
    F = 0.8
    vi = _decoupled(seed, dim, F, "symmetric")
    normal, _ = _rows(vi, dim, 1)
    frictionless = solve(_decoupled(seed, dim, 0.0, "symmetric"), "ssn", tol=1e-12, **FAST)
    lam_n = frictionless.lam[normal]
    assert (lam_n > 0).sum() >= 1
    ref, lam_ref = _tresca_reference(vi, dim, F * lam_n)
    newton, fixed = _both(vi)
    assert newton.converged and fixed.converged and fixed.iterations == 2
    scale = np.abs(lam_ref).max()
    for sol in (newton, fixed):
        assert np.abs(sol.lam - lam_ref).max() <= 1e-8 * scale
        assert np.abs(sol.u - ref.u).max() <= 1e-8 * np.abs(ref.u).max()


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(3))
def test_large_friction_sticks(seed, dim):
    """F → ∞: every node in contact sticks. Reference: the decoupled problem with Free
    tangential rows on the contact nodes of the frictionless solve and no tangential rows
    elsewhere (a linear solve once the normal part is known)."""
    vi = _decoupled(seed, dim, 1e6)
    normal, tangential = _rows(vi, dim, 1)
    lam_n = solve(_decoupled(seed, dim, 0.0), "ssn", tol=1e-12, **FAST).lam[normal]
    # in contact: a pressure above rounding, the checker's rule (λ_n > 1e-10 of the largest);
    # a node touching with a rounding-level pressure is open or stuck depending on the rounding
    contact = lam_n > 1e-10 * np.abs(lam_n).max()
    T = tangential.reshape(-1, dim - 1)
    keep = np.concatenate([np.arange(1), normal, T[contact].ravel()])
    Lam = product(Free(1), NonNegative(normal.size), Free(T[contact].size))
    ref = solve(MixedVI(A=vi.A, B=vi.B[keep], f=vi.f, gap=vi.gap[keep], Lambda=Lam), "ssn",
                tol=1e-12, **FAST)  # fmt: skip
    lam_ref = np.zeros(vi.m)
    lam_ref[keep] = ref.lam
    newton, fixed = _both(vi)
    for sol in (newton, fixed):
        assert sol.converged
        counts = Checker.of(vi).contact(sol.u, sol.lam)
        assert counts.slip == 0 and counts.stick == contact.sum()
        assert np.abs(sol.lam - lam_ref).max() <= 1e-8 * np.abs(lam_ref).max()


def test_tresca_only_in_contact_frees_the_open_nodes():
    """UnilateralTresca(contact_only=True): no tangential force on nodes that lift off; with
    contact_only=False the bound acts there too (and the answer differs). Both paths agree."""
    dim = 2
    vi = random_contact_vi(5, n=24, k=6, dim=dim, F=0.3, law="tresca", structure="general")
    normal, tangential = _rows(vi, dim, 0)
    newton, fixed = _both(vi)
    assert newton.converged and fixed.converged
    _judged(vi, newton)
    du, dl = agree(vi, fixed, newton)
    assert du <= AGREE and dl <= AGREE
    is_open = newton.lam[normal] == 0
    assert is_open.any() and (~is_open).any()
    assert (newton.lam[tangential][is_open] == 0).all()
    everywhere = MixedVI(A=vi.A, B=vi.B, f=vi.f, gap=vi.gap,
                         Lambda=UnilateralTresca(0.3, dim, contact_only=False, k=6))  # fmt: skip
    classic = solve(everywhere, "ssn", tol=TOL, **FAST)
    assert classic.converged and not everywhere.Lambda.quasi
    assert np.abs(classic.lam[tangential][is_open]).max() > 1e-3


# ---------------------------------------------------------------------- not converged
def test_not_converged_is_said_never_answered():
    """Beyond the range: F = 5 on this gallery problem — Newton stalls and the fixed point
    stops contracting; each says so (converged False, a warning, residual > tol)."""
    vi = random_contact_vi(2, n=20, k=4, dim=2, F=5.0, structure="symmetric", free=2)
    newton, fixed = _both(vi)
    for sol in (newton, fixed):
        assert not sol.converged and sol.residual > TOL and sol.warnings
        assert Checker.of(vi)(sol.u, sol.lam).relative > 1e-6
    assert "did not shrink" in " ".join(fixed.warnings)
    short = solve(random_contact_vi(1, F=0.3, free=2), "fixed_point", tol=TOL, max_iter=2, **FAST)
    assert not short.converged and "did not reach tol" in short.warnings[-1]


def test_dispatcher():
    vi = random_contact_vi(2, n=20, k=4, dim=2, F=0.3, structure="skew-coupled", free=2)
    for method in ("conic", "homotopy"):
        with pytest.raises(ValueError, match=f'allowed: auto, ssn, fixed_point .*"{method}"'):
            solve(vi, method)
    with pytest.raises(ValueError, match="has none: allowed: auto, ssn, conic, homotopy"):
        solve(MixedVI(A=np.eye(2), B=np.eye(2), f=np.ones(2), Lambda=Free(2)), "fixed_point")
    sol = solve(vi, "auto", tol=TOL, max_iter=1, **FAST)  # one Newton step cannot make it
    assert sol.converged and sol.method == "fixed_point"
    assert sol.info["auto"]["chosen"] == "fixed_point"


def test_tresca_sequence_orders_rows_normals_first():
    vi = random_contact_vi(0, n=24, k=3, dim=3, F=0.3, free=2)
    seq = TrescaSequence(vi)
    assert seq.perm.tolist() == [0, 1, 2, 5, 8, 3, 4, 6, 7, 9, 10]
    sub = seq.problem(seq.bounds(np.arange(vi.m, dtype=float)))
    assert [type(b).__name__ for b in sub.Lambda.blocks()] == ["Free", "NonNegative", "Ball"]
    assert np.allclose(sub.Lambda.blocks()[2].radius, 0.3 * np.array([2.0, 5.0, 8.0]))
    assert sp.linalg.norm(sub.B - vi.B[seq.perm]) == 0


# ---------------------------------------------------------------------- the checker
def test_checker_sees_each_contact_fault():
    """A converged answer passes; each condition fails on its own when broken."""
    dim = 2
    vi = random_contact_vi(4, n=24, k=6, dim=dim, F=0.4, structure="general")
    sol = solve(vi, "ssn", tol=1e-12, **FAST)
    check = Checker.of(vi)
    good = check.contact(sol.u, sol.lam)
    assert good.worst <= 1e-10 and good.stick + good.slip >= 2 and good.open >= 1
    normal, tangential = _rows(vi, dim, 0)
    pressed = np.flatnonzero(sol.lam[normal] > 0)

    def broken(change):
        lam = sol.lam.copy()
        change(lam)
        return check.contact(sol.u, lam)

    def negative(lam):
        lam[normal[pressed[0]]] *= -1

    def outside(lam):
        lam[tangential[pressed[0]]] = 3 * 0.4 * lam[normal[pressed[0]]]

    def flipped(lam):
        lam[tangential[pressed]] *= -1

    assert broken(negative).normal_sign > 1e-3
    assert broken(outside).cone > 1e-3
    slipping = np.abs((vi.B @ sol.u - vi.gap)[tangential[pressed]]) > 1e-6
    assert slipping.any()  # the draw has a slipping node: the alignment can fail
    assert broken(flipped).alignment > 1e-3
    lifted = check.contact(sol.u + 1e3 * np.linalg.lstsq(vi.B.toarray(), -np.eye(vi.m)[:, 0],
                                                          rcond=None)[0], sol.lam)  # fmt: skip
    assert lifted.penetration > 1e-3 or lifted.normal_complementarity > 1e-3


def test_mutation_wrong_radius_is_caught(monkeypatch):
    """Mutation: the radius g = F instead of F·λ_n (Tresca with the coefficient as bound).
    Newton converges on the faulty map; the checker and the cross-check with the fixed point
    (which reads `tresca_bound`, unmutated) do not accept it."""
    vi = random_contact_vi(4, n=24, k=6, dim=2, F=0.4, structure="general")
    truth = solve(vi, "ssn", tol=1e-12, **FAST)
    monkeypatch.setattr(Coulomb, "radius", lambda self, yn: (self.F.copy(), np.zeros(self.k)))
    wrong = solve(vi, "ssn", tol=1e-12, **FAST)
    assert wrong.converged  # the solver is fooled …
    assert np.abs(wrong.lam - truth.lam).max() > 1e-3
    check = Checker.of(vi)
    assert check(wrong.u, wrong.lam).relative > 1e-4  # … the checker is not
    assert check.contact(wrong.u, wrong.lam).worst > 1e-4


def test_mutation_dropped_normal_complementarity_is_caught(monkeypatch):
    """Mutation: the normal NCP dropped (P_n(y) = y_n: bilateral contact). Newton converges on
    the faulty map; λ_n < 0 on the lifting nodes is seen by the checker."""
    vi = random_contact_vi(4, n=24, k=6, dim=2, F=0.4, structure="general")
    project, jacobian = coulomb_module.ContactSet.project, coulomb_module.ContactSet.jacobian

    def bilateral_project(self, y):
        out = project(self, y).reshape(self.k, self.dim)
        out[:, 0] = np.asarray(y, float).reshape(self.k, self.dim)[:, 0]
        return out.ravel()

    def bilateral_jacobian(self, y):
        J = jacobian(self, y).tolil()
        for j in range(self.k):
            J[self.dim * j, self.dim * j] = 1.0
        return J.tocsr()

    monkeypatch.setattr(coulomb_module.ContactSet, "project", bilateral_project)
    monkeypatch.setattr(coulomb_module.ContactSet, "jacobian", bilateral_jacobian)
    wrong = solve(vi, "ssn", tol=1e-12, **FAST)
    assert wrong.converged  # the solver is fooled …
    check = Checker.of(vi)
    assert check.contact(wrong.u, wrong.lam).normal_sign > 1e-3  # … the checker is not
    assert check(wrong.u, wrong.lam).relative > 1e-4


# ---------------------------------------------------------------------- the update, by hand
# The multiplier update of semismooth Newton is the combined map P(y), y = λ + c(Bu − gap), node
# by node: (y_n, y_t) → (max(y_n, 0), y_t clipped to the radius ρ). Two nodes per set, worked
# out on paper: Coulomb ρ = F·y_n⁺; unilateral Tresca ρ = g where y_n > 0, 0 apart; classical
# Tresca (contact_only=False) ρ = g on every node.
BY_HAND = [
    # F = 0.5: ρ = 1, y_t = 3 slips to 1; node 1 is apart: (0, 0)
    (lambda: Coulomb([0.5, 2.0], 2), [2.0, 3.0, -1.0, 0.7], [2.0, 1.0, 0.0, 0.0]),
    # ρ = 2: y_t = −1 sticks; ρ = 2: y_t = −5 slips to −2
    (lambda: Coulomb([0.5, 2.0], 2), [4.0, -1.0, 1.0, -5.0], [4.0, -1.0, 1.0, -2.0]),
    # 3D: ρ = 1, y_t = (3, 4) of length 5 → (0.6, 0.8); ρ = 1, |(0.3, −0.4)| = 0.5 sticks
    (
        lambda: Coulomb([0.5, 1.0], 3),
        [2.0, 3.0, 4.0, 1.0, 0.3, -0.4],
        [2.0, 0.6, 0.8, 1.0, 0.3, -0.4],
    ),
    # g = 1.5 in contact: −3 → −1.5; apart: nothing transmitted
    (lambda: UnilateralTresca([1.5, 0.4], 2), [2.0, -3.0, -1.0, 0.3], [2.0, -1.5, 0.0, 0.0]),
    # the classical Tresca problem bounds λ_t apart too: 0.3 ≤ 0.4 kept
    (
        lambda: UnilateralTresca([1.5, 0.4], 2, False),
        [2.0, -3.0, -1.0, 0.3],
        [2.0, -1.5, 0.0, 0.3],
    ),
]


def _by_hand_mismatch() -> float:
    """The largest difference between P(y) and the values worked out by hand."""
    return max(
        float(np.abs(make().project(np.array(y)) - np.array(p)).max()) for make, y, p in BY_HAND
    )


def test_the_update_is_the_projection_worked_out_by_hand():
    assert _by_hand_mismatch() <= 1e-15


def _flip_tangential(project):
    def flipped(self, y):
        out = project(self, y).reshape(self.k, self.dim)
        out[:, 1:] *= -1.0  # −y_t clipped: still inside the cone, the wrong direction
        return out.ravel()

    return flipped


def _flip_normal(project):
    def flipped(self, y):
        out = project(self, y).reshape(self.k, self.dim)
        out[:, 0] = np.maximum(-np.asarray(y, float).reshape(self.k, self.dim)[:, 0], 0.0)
        return out.ravel()

    return flipped


@pytest.mark.parametrize("fault", [_flip_tangential, _flip_normal], ids=["tangential", "normal"])
def test_mutation_a_sign_flip_in_the_update_fails_the_hand_values(fault, monkeypatch):
    monkeypatch.setattr(
        coulomb_module.ContactSet, "project", fault(coulomb_module.ContactSet.project)
    )
    assert _by_hand_mismatch() > 0.5
    if fault is _flip_tangential:  # the set-membership test above cannot see this one
        S = Coulomb([0.5, 2.0], 2)
        P = S.project(np.array([2.0, 3.0, 1.0, -5.0])).reshape(2, 2)
        assert (np.abs(P[:, 1]) <= S.F * P[:, 0]).all()


def _rim_points(S, rng: np.random.Generator, rel: float) -> np.ndarray:
    """A random y with every node's |y_t| = ρ(y_n)·(1 + rel): on the rim, off it by `rel`."""
    Y = rng.standard_normal((S.k, S.dim))
    Y[:, 0] = rng.uniform(0.5, 2.0, S.k)
    r, _ = S.radius(Y[:, 0])
    Y[:, 1:] *= (r * (1.0 + rel) / np.linalg.norm(Y[:, 1:], axis=1))[:, None]
    return Y.ravel()


@given(
    st.integers(0, 2**32 - 1),
    st.sampled_from(sorted(SETS)),
    st.sampled_from((2, 3)),
    st.sampled_from((-1e-14, -2.2e-16, 0.0, 2.2e-16, 1e-14)),
)
@settings(max_examples=20)
def test_a_node_on_the_rim_by_rounding_sticks(seed, kind, dim, rel):
    """|y_t| = ρ(1 ± a few ulp) — every slipping node of a load step's warm start — gets the
    sticking derivative (identity tangential block) whichever side rounding put it on, so two
    engines that agree to rounding take the same Newton steps (vi_core.sets.TIE); a node off
    the rim by 1e-9 gets the slip derivative."""
    rng = np.random.default_rng(seed)
    S = SETS[kind](rng, dim)
    t = dim - 1
    blocks = S.jacobian(_rim_points(S, rng, rel)).toarray()
    for j in range(S.k):
        tan = blocks[j * dim + 1 : (j + 1) * dim, j * dim + 1 : (j + 1) * dim]
        np.testing.assert_array_equal(tan, np.eye(t))
    blocks = S.jacobian(_rim_points(S, rng, 1e-9)).toarray()
    for j in range(S.k):
        tan = blocks[j * dim + 1 : (j + 1) * dim, j * dim + 1 : (j + 1) * dim]
        assert not np.array_equal(tan, np.eye(t))


def test_a_ball_node_on_the_rim_by_rounding_is_inside():
    """The Tresca disc (`Ball`) decides its rim by the same rule."""
    rng = np.random.default_rng(3)
    B = Ball(rng.uniform(0.5, 2.0, 5), 2)
    Y = rng.standard_normal((5, 2))
    for rel, inside in ((1e-14, True), (-1e-14, True), (1e-9, False)):
        Yr = Y * (B.radius * (1 + rel) / np.linalg.norm(Y, axis=1))[:, None]
        J = B.jacobian(Yr.ravel()).toarray()
        assert np.array_equal(J, np.eye(10)) is inside


@pytest.mark.parametrize("band", [0.0, -1e-12])
def test_mutation_rim_decided_by_rounding_is_caught(band, monkeypatch):
    """Without the band (strict `>` as before) or with it turned the other way, a node at
    ρ(1 + 1e-14) slips: the rim test above fails."""
    import vi_core.sets as sets_module

    monkeypatch.setattr(sets_module, "TIE", band)
    rng = np.random.default_rng(0)
    S = Coulomb(rng.uniform(0.5, 2.0, 6), 3)
    J = S.jacobian(_rim_points(S, rng, 1e-14)).toarray()
    tan = [J[3 * j + 1 : 3 * j + 3, 3 * j + 1 : 3 * j + 3] for j in range(6)]
    assert not all(np.array_equal(b, np.eye(2)) for b in tan)
