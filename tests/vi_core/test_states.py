"""The state rule (vi_core.states): evidence both ways, thresholds from the residual and the
scales, ambiguity counted, and mutations of the rule and the comparison that must be caught."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from vi_core import states


def _strip(seed: int, scale_lam: float, scale_u: float, res: float):
    """Nodes with known states: stick (margin > 0, no slip), slip (on the bound, moving) and
    open (no pressure, a gap), perturbed by `res` relative noise."""
    rng = np.random.default_rng(seed)
    k = 12
    truth = rng.choice(np.array(["stick", "slip", "open"], dtype=object), size=k)
    lam_n = np.where(truth == "open", 0.0, scale_lam * rng.uniform(0.5, 1.0, k))
    gap = np.where(truth == "open", scale_u * rng.uniform(0.1, 1.0, k), 0.0)
    rho = 0.4 * lam_n
    lam_t = np.where(truth == "stick", rho * rng.uniform(0.1, 0.9, k), rho)
    slip = np.where(truth == "slip", scale_u * rng.uniform(0.1, 1.0, k), 0.0)
    noise = lambda s: s * res * rng.uniform(-1, 1, k)  # noqa: E731
    lam_t = lam_t - np.abs(noise(scale_lam))  # the fixed point stops just below the bound
    return truth, lam_n + noise(scale_lam), gap + noise(scale_u), lam_t, rho, slip + noise(scale_u)


def _label(lam_n, gap, lam_t, rho, slip, res, scale_lam, scale_u):
    th = states.thresholds(res, scale_lam, scale_u)
    return states.node_states(
        states.normal_states(lam_n, gap, th), states.tangential_states(lam_t, rho, slip, th)
    )


@given(
    seed=st.integers(0, 2**31),
    scale_lam=st.floats(1e-8, 1e11),
    scale_u=st.floats(1e-9, 1e2),
    res=st.floats(1e-15, 1e-6),
)
def test_states_exact_at_any_scale_and_residual(seed, scale_lam, scale_u, res):
    truth, lam_n, gap, lam_t, rho, slip = _strip(seed, scale_lam, scale_u, res)
    got = _label(lam_n, gap, lam_t, rho, slip, res, scale_lam, scale_u)
    assert list(got) == list(truth)


def test_fixed_1e9_margin_rule_mislabels_the_fixed_point_case():
    """The issue's case: λ_t 1e-8 below Fλ_n with full slip reads as stick under the old
    margin-only rule, as slip under the new one."""
    rho = np.full(4, 3.5e5)
    lam_t = rho - 1e-8 * 3.5e5
    old = np.abs(lam_t) >= rho - 1e-9 * rho.max()
    assert not old.any()
    th = states.thresholds(1e-8, 7e5, 1e-3)
    assert list(states.tangential_states(lam_t, rho, np.full(4, 6.5e-4), th)) == ["slip"] * 4


def test_at_the_flip_ambiguous_not_wrong():
    th = states.thresholds(1e-10, 1.0, 1.0)
    # on the bound with zero slip: both states fit within tolerance
    assert states.tangential_states([1.0], [1.0], [0.0], th)[0] == "ambiguous"
    # evidence both ways at once (a contradiction at this tolerance) is ambiguous too
    assert states.tangential_states([0.5], [1.0], [0.5], th)[0] == "ambiguous"
    assert states.normal_states([0.0], [0.0], th)[0] == "ambiguous"


def test_compare_counts_ambiguity_and_flags_a_flip():
    a = np.array(["stick", "slip", "ambiguous", "open"], dtype=object)
    r = states.compare(a, a.copy())
    assert r["disagree"] == 0 and r["ambiguous"] == 1 and r["agree"] == 3
    b = a.copy()
    b[1] = "stick"  # one node flipped
    r = states.compare(a, b)
    assert r["disagree"] == 1 and r["disagree_nodes"] == [1]
    b = a.copy()
    b[0] = "ambiguous"
    assert states.compare(a, b)["disagree"] == 0


# ------------------------------------------------------------------ mutations of the rule
def _mut_sign(lam_t, rho, slip, th):
    margin = np.abs(lam_t) - np.asarray(rho)  # sign flipped
    held, moved = margin > th.lam, np.abs(slip) > th.u
    return np.where(held & ~moved, "stick", np.where(moved & ~held, "slip", "ambiguous"))


def _mut_fixed(lam_t, rho, slip, th):
    th = states.Thresholds(1e-9, 1e-9)  # scaling dropped
    return states.tangential_states(lam_t, rho, slip, th)


def _mut_no_slip_evidence(lam_t, rho, slip, th):
    return states.tangential_states(lam_t, rho, np.zeros_like(np.asarray(slip)), th)


@pytest.mark.parametrize("mutant", [_mut_sign, _mut_fixed, _mut_no_slip_evidence])
def test_mutations_of_the_rule_are_caught(mutant):
    """Each fault gives a wrong label somewhere in the scaled cases (stiffness 1e11 Pa next to
    1e-8; the fixed point's shortfall on the bound)."""
    caught = False
    for seed, scale_lam, scale_u, res in [(1, 1e11, 1e-3, 1e-8), (2, 1e-8, 1e-9, 1e-12)]:
        truth, lam_n, gap, lam_t, rho, slip = _strip(seed, scale_lam, scale_u, res)
        th = states.thresholds(res, scale_lam, scale_u)
        good = states.tangential_states(lam_t, rho, slip, th)
        bad = mutant(lam_t, rho, slip, th)
        touch = truth != "open"
        assert list(good[touch]) == list(truth[touch])
        caught |= list(bad[touch]) != list(truth[touch])
    assert caught


def _cmp_ignores_states(a, b):
    return {"disagree": 0}


def _cmp_flips_a_node(a, b):
    b = np.asarray(b, dtype=object).copy()
    b[0] = "slip" if b[0] != "slip" else "stick"
    return states.compare(a, b)


@pytest.mark.parametrize("mutant", [_cmp_ignores_states, _cmp_flips_a_node])
def test_mutations_of_the_comparison_are_caught(mutant):
    a = np.array(["stick", "slip", "slip", "open"], dtype=object)
    b = a.copy()
    b[2] = "stick"
    same = a.copy()
    # the real comparison: disagreement found, agreement clean
    real = (states.compare(a, b)["disagree"], states.compare(a, same)["disagree"])
    assert real == (1, 0)
    assert (mutant(a, b)["disagree"], mutant(a, same)["disagree"]) != real


# ------------------------------------------------------------------ on a VI's own rows
def _node_springs(seed: int):
    """k contact nodes, each a spring pair of stiffness a = a₀ w behind a Coulomb node of
    weight w (B = w per row, graded 1e-6 … 1), loaded by the pressure p: pushed in
    (f_n = p w) it touches with λ_n = p and sticks where |f_t| < F f_n (λ_t = f_t/w, u_t = 0)
    or slips (λ_t = ±F λ_n, u_t = (f_t − w λ_t)/a, a length independent of w); pulled
    (f_n = −p w) it is open (λ = 0, u = f/a). The exact answer and the states."""
    import scipy.sparse as sp

    from vi_core import Coulomb, MixedVI

    rng = np.random.default_rng(seed)
    k = 10
    truth = rng.choice(np.array(["stick", "slip", "open"], dtype=object), size=k)
    w = 10 ** rng.uniform(-6, 0, k)
    a = rng.uniform(1.0, 10.0, k) * w
    F = rng.uniform(0.2, 1.0, k)
    p = rng.uniform(0.5, 2.0, k)
    fn = np.where(truth == "open", -1.0, 1.0) * p * w
    ratio = np.where(truth == "stick", rng.uniform(0.2, 0.8, k), rng.uniform(1.2, 3.0, k))
    ft = ratio * F * np.abs(fn) * rng.choice([-1.0, 1.0], k)
    lam_n = np.where(truth == "open", 0.0, fn / w)
    lam_t = np.where(truth == "stick", ft / w, np.sign(ft) * F * lam_n)
    u_n = np.where(truth == "open", fn / a, 0.0)
    u_t = np.where(truth == "stick", 0.0, (ft - w * lam_t) / a)
    inter = lambda x, y: np.column_stack([x, y]).ravel()  # noqa: E731 node by node [n, t]
    vi = MixedVI(
        A=sp.diags(np.repeat(a, 2)).tocsr(),
        B=sp.diags(np.repeat(w, 2)).tocsr(),
        f=inter(fn, ft),
        Lambda=Coulomb(F, 2),
    )
    return vi, inter(u_n, u_t), inter(lam_n, lam_t), truth


@given(seed=st.integers(0, 2**31))
def test_vi_states_of_the_exact_answer_and_the_fixed_point(seed):
    from vi_core import solve

    vi, u, lam, truth = _node_springs(seed)
    res = vi.residual(u, lam).relative
    assert list(states.vi_states(vi, u, lam, res)) == list(truth)
    fp = solve(vi, "fixed_point", tol=1e-10)
    assert fp.converged and fp.info["states"]["counts"] == states.counts(truth)
    assert list(states.vi_states(vi, fp.u, fp.lam, fp.residual)) == list(truth)


def test_vi_states_without_row_weights_is_caught(monkeypatch):
    """Mutation: the rows' jumps not divided by their weight W_k (graded 1e-6 … 1): at a
    residual of 1e-6 a slip at a light node falls below the threshold, while the real rule
    still labels every node right."""
    wrong = 0
    for seed in range(6):
        vi, u, lam, truth = _node_springs(seed)
        res = 1e-6
        assert list(states.vi_states(vi, u, lam, res)) == list(truth)
        with monkeypatch.context() as m:
            m.setattr(states, "_row_weights", lambda B: np.ones(B.shape[0]))
            wrong += list(states.vi_states(vi, u, lam, res)) != list(truth)
    assert wrong


@given(
    seed=st.integers(0, 2**31),
    scale_lam=st.floats(1e-8, 1e11),
    scale_u=st.floats(1e-9, 1e2),
    res=st.floats(1e-18, 1e-15),
    mutate=st.booleans(),
)
def test_solution_thresholds_read_the_steps_accuracy(seed, scale_lam, scale_u, res, mutate):
    """A frictionless touching node (ρ = 0) whose slip is 0 exactly but reads noise at the
    accuracy of an iterative last step (rtol 1e-12, far above the residual it reached) is
    "ambiguous", as after a direct solve, not "slip"; a node that slips by a fraction of the
    scale still reads "slip". Mutation (mutate): the accuracy not recorded: the noise reads as
    slip (the label follows a 1e-14 difference: hertz's node on the petsc engine's amg path)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(seed)
    acc = 1e-12
    info = {} if mutate else {"states": {"accuracy": acc}}
    sol = SimpleNamespace(residual=res, info=info)
    th = states.solution_thresholds(sol, scale_lam, scale_u)
    slip = np.array([acc * scale_u * rng.uniform(0.5, 1.0), scale_u * rng.uniform(0.1, 1.0)])
    lam_n = scale_lam * rng.uniform(0.5, 1.0, 2)
    normal = states.normal_states(lam_n, np.zeros(2), th)
    labels = states.node_states(
        normal, states.tangential_states(np.zeros(2), np.zeros(2), slip, th)
    )
    assert labels[1] == "slip"
    assert (labels[0] == "ambiguous") != mutate
