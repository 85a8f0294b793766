"""Nested iteration's warm start of piezo_contact: the stick/slip prediction at a transition
(`piezo_contact._slip_ahead`), checked against an independent computation and, on the paper
scene, against the fine level's own solution."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from problems.plugins import piezo_contact as pc
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
    return pc._slip_ahead(xc, np.where(np.abs(ratio) >= 1 - 1e-9, 0.5, 1.0), xf)


def _mismatches(fn, seeds) -> int:
    return sum(int((fn(*_profile(s)) != _expected(*_profile(s))).sum()) for s in seeds)


@given(st.integers(0, 2**32 - 1))
def test_slip_ahead_matches_the_rule(seed):
    xc, ratio, xf = _profile(seed)
    np.testing.assert_array_equal(pc._slip_ahead(xc, ratio, xf), _expected(xc, ratio, xf))


def test_slip_ahead_check_catches_faults():
    """The check above fails for a wrong side, a dropped extrapolation, a flipped test."""
    seeds = range(200)
    assert _mismatches(pc._slip_ahead, seeds) == 0
    assert _mismatches(_wrong_side, seeds) > 0
    assert _mismatches(lambda xc, r, xf: np.zeros(xf.size, dtype=bool), seeds) > 0
    assert _mismatches(lambda xc, r, xf: ~pc._slip_ahead(xc, r, xf), seeds) > 0


def _predicted_and_final(level: int, slip_ahead) -> tuple[np.ndarray, np.ndarray]:
    """The warm start's slip rows of `level` (nested from level − 1) and the solution's."""
    scene = load_scene("paper_two_body")
    coarse = pc.build(scene, level - 1)
    cs = solve(coarse.vi, "ssn", tol=1e-12)
    fine = pc.build(scene, level)
    original = pc._slip_ahead
    pc._slip_ahead = slip_ahead
    try:
        lam0 = pc.warm_start(coarse, cs, fine)["lam0"]
    finally:
        pc._slip_ahead = original
    sol = solve(fine.vi, "ssn", tol=1e-12, lam0=lam0)
    c = fine.contact

    def on_bound(lam):
        return np.abs(c.tangential(lam)) >= c.bound(lam) * (1 - 1e-9)

    return on_bound(lam0), on_bound(sol.lam)


@pytest.mark.slow
def test_warm_start_predicts_the_fine_slip_rows():
    """Paper scene, level 4 from level 3: the predicted slip rows are the solution's (then one
    Newton step solved to tol is the answer); interpolation alone misses the two new nodes at
    the transitions (the mutation: `_slip_ahead` dropped)."""
    predicted, final = _predicted_and_final(4, pc._slip_ahead)
    np.testing.assert_array_equal(predicted, final)
    predicted, final = _predicted_and_final(4, lambda xc, r, xf: np.zeros(xf.size, dtype=bool))
    assert (predicted != final).sum() == 2
