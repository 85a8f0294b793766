"""Nested iteration's warm start of piezo_contact: the stick/slip prediction at a transition
(`warm_starts._slip_ahead`), checked against an independent computation and, on the paper
scene, against the fine level's own solution."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from problems.plugins.contact import plane as pc
from problems.plugins.contact import warm_starts
from problems.plugins.contract import nested_start
from problems.scene import load_scene
from vi_core import solve


def _profile(seed: int):
    """Coarse positions (K,), ratios with stick runs and slip runs (±1), the fine positions
    (the coarse ones and every midpoint, as uniform refinement makes them)."""
    rng = np.random.default_rng(seed)
    K = int(rng.integers(3, 12))
    xc = np.cumsum(rng.uniform(0.1, 1.0, K))
    slip = rng.random(K) < 0.5
    ratio = np.where(slip, rng.choice([-1.0, 1.0], K), rng.uniform(-0.99, 0.99, K))
    xf = np.sort(np.concatenate([xc, 0.5 * (xc[1:] + xc[:-1])]))
    return xc, ratio, xf


def _expected(xc, ratio, xf) -> np.ndarray:
    """The rule written again, node by node: a fine node strictly inside a coarse interval
    with one stick end a and one slip end; b the neighbour of a away from the slip end, also
    stick; the line through (x_b, |r_b|) and (x_a, |r_a|) at the node is ≥ 1."""
    slip = np.abs(ratio) >= 1.0 - 1e-9
    out = np.zeros(xf.size, dtype=bool)
    for i, x in enumerate(xf):
        for k in range(xc.size - 1):
            if not xc[k] < x < xc[k + 1] or slip[k] == slip[k + 1]:
                continue
            a, b = (k, k - 1) if slip[k + 1] else (k + 1, k + 2)
            if 0 <= b < xc.size and not slip[b]:
                line = np.polyfit([xc[b], xc[a]], [abs(ratio[b]), abs(ratio[a])], 1)
                out[i] = np.polyval(line, x) >= 1.0
    return out


def _wrong_side(xc, ratio, xf):
    """A fault to catch: extrapolation from the slip end instead of the stick end."""
    return warm_starts._slip_ahead(xc, np.where(np.abs(ratio) >= 1 - 1e-9, 0.5, 1.0), xf)


def _mismatches(fn, seeds) -> int:
    return sum(int((fn(*_profile(s)) != _expected(*_profile(s))).sum()) for s in seeds)


@given(st.integers(0, 2**32 - 1))
def test_slip_ahead_matches_the_rule(seed):
    xc, ratio, xf = _profile(seed)
    np.testing.assert_array_equal(warm_starts._slip_ahead(xc, ratio, xf), _expected(xc, ratio, xf))


def test_slip_ahead_check_catches_faults():
    """The check above fails for a wrong side, a dropped extrapolation, a flipped test."""
    seeds = range(200)
    assert _mismatches(warm_starts._slip_ahead, seeds) == 0
    assert _mismatches(_wrong_side, seeds) > 0
    assert _mismatches(lambda xc, r, xf: np.zeros(xf.size, dtype=bool), seeds) > 0
    assert _mismatches(lambda xc, r, xf: ~warm_starts._slip_ahead(xc, r, xf), seeds) > 0


def _predicted_and_final(level: int, slip_ahead) -> tuple[np.ndarray, np.ndarray]:
    """The warm start's slip rows of `level` (nested from level − 1) and the solution's."""
    scene = load_scene("paper_two_body")
    coarse = pc.build(scene, level - 1)
    cs = solve(coarse.vi, "ssn", tol=1e-12)
    fine = pc.build(scene, level)
    original = warm_starts._slip_ahead
    warm_starts._slip_ahead = slip_ahead
    try:
        lam0 = pc.warm_start(coarse, cs, fine)["lam0"]
    finally:
        warm_starts._slip_ahead = original
    sol = solve(fine.vi, "ssn", tol=1e-12, lam0=lam0)
    c = fine.contact

    def on_bound(lam):
        return np.abs(c.tangential(lam)) >= c.bound(lam)[c.rows_t] * (1 - 1e-9)

    return on_bound(lam0), on_bound(sol.lam)


@pytest.mark.slow
def test_warm_start_predicts_the_fine_slip_rows():
    """Paper scene, level 4 from level 3: the predicted slip rows are the solution's (then one
    Newton step solved to tol is the answer); interpolation alone misses the two new nodes at
    the transitions (the mutation: `_slip_ahead` dropped)."""
    predicted, final = _predicted_and_final(4, warm_starts._slip_ahead)
    np.testing.assert_array_equal(predicted, final)
    predicted, final = _predicted_and_final(4, lambda xc, r, xf: np.zeros(xf.size, dtype=bool))
    assert (predicted != final).sum() == 2


def _carried(level: int) -> tuple[dict, bool, np.ndarray]:
    """The warm start of `level` (from level − 1), whether the first Newton step from it ties
    the rows the fine solution ties (its active set, y = λ0 + B u0 − gap), and the relative
    error of u0 against the fine solution, per field (displacement, potential)."""
    scene = load_scene("paper_two_body")
    coarse = pc.build(scene, level - 1)
    fine = pc.build(scene, level)
    kw, start = nested_start(pc, coarse, solve(coarse.vi, "ssn", tol=1e-12), fine)
    sol = solve(fine.vi, "ssn", tol=1e-12, **kw)
    e, sc = fine.vi.equilibrated, fine.vi.scaling

    def tied(lam, u):  # the rows ssn's Newton step ties at (u, λ) (W = I − J zero)
        y = lam / sc.s_lam + e.B @ (u / sc.s_u) - e.gap  # in ssn's (equilibrated) units
        W = sp.identity(e.m) - e.Lambda.jacobian(y)
        return np.asarray(abs(W).sum(axis=1)).ravel() == 0

    same = np.array_equal(tied(kw["lam0"], kw["u0"]), tied(sol.lam, sol.u))
    err = np.array([
        np.linalg.norm(kw["u0"][m] - sol.u[m]) / np.linalg.norm(sol.u[m])
        for m in fine.unknown_fields().values()
    ])  # fmt: skip
    return start, same, err


def test_warm_start_carries_the_coarse_displacement_and_potential():
    """Paper scene, level 2 from level 1: u0 is the coarse solution prolongated (0.7 % and
    1.7 % from the fine solution in displacement and potential) and the first active set is
    the solution's; the mutation (the prolongation dropped: u0 = 0 but on the tied slave
    dofs) is ~100 % off."""
    start, same, err = _carried(2)
    assert start["carries"] == ["lam0", "u0"] and start["outside_nodes"] > 0  # the curved arc
    assert same and (err <= 0.05).all(), err
    original = warm_starts.transfer.prolongate
    warm_starts.transfer.prolongate = lambda c, x, f: (np.zeros(f.values.size), 0)
    try:
        assert (_carried(2)[2] > 0.5).all()
    finally:
        warm_starts.transfer.prolongate = original


@pytest.mark.slow
def test_tied_warm_start_keeps_the_predicted_slip_rows():
    """Level 3 from level 2: with u0 tied on the rows λ0 predicts stick the first active set is
    the solution's; untied (the mutation), the interpolated jump beside both stick/slip
    transitions calls two stick rows slip."""
    assert _carried(3)[1]
    original = warm_starts.transfer.tied_start
    warm_starts.transfer.tied_start = lambda vi, u0, lam0, tied: u0
    try:
        assert not _carried(3)[1]
    finally:
        warm_starts.transfer.tied_start = original
