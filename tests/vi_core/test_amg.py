"""The memory-lean smoothed-aggregation hierarchy (`vi_core.amg`) against pyamg's."""

import numpy as np
import pytest
import scipy.sparse as sp

from vi_core import amg
from vi_core.tied_preconditioner import TiedPreconditioner

pytest.importorskip("pyamg")


@pytest.mark.parametrize("field", ["displacement", "potential"])
def test_smoothed_aggregation_is_pyamgs_hierarchy(field, monkeypatch):
    """The memory-lean hierarchy (`smoothed_aggregation`: `strength_within_parts` from A's
    structure, `energy_smoothing` on the finest level, the coarser levels' strength cut
    between the parts of their aggregates) is pyamg's smoothed_aggregation_solver with
    pyamg's strength cut between the bodies on every level, to rounding: the operators of
    every level and one W-cycle. Mutations: one CG step of the energy smoothing fewer, the
    strength not cut between the bodies on the finest level, or not on the coarser ones, are
    not."""
    import pyamg

    from problems.plugins.contact import plane as pc
    from problems.scene import load_scene
    from vi_core.ssn import Condensation

    e = pc.build(load_scene("paper_two_body"), 3).vi.equilibrated  # 3 AMG levels
    ks = TiedPreconditioner(e.A, e.B, Condensation.detect(e.B), e.fields, e.near_null)
    tied = np.ones(e.m, dtype=bool)  # every row tied: the bodies glued, Â couples them
    blk = next(b for b in ks._blocks(tied) if b["name"] == field)
    A, nn = blk["sym"], blk["nn"]
    part = np.concatenate([amg.bodies(e.A)[ks.R], amg.bodies(e.A)[ks.S][~tied]])[blk["index"]]

    def cut(C, part):  # pyamg's strength C with the connections between two parts dropped
        C = sp.coo_matrix(C)
        keep = part[C.row] == part[C.col]
        return sp.csr_matrix((C.data[keep], (C.row[keep], C.col[keep])), shape=C.shape), keep

    # the reference: pyamg's symmetric strength (θ = 0) cut between the bodies on the finest
    # level, then level by level between the parts of the aggregates (each aggregate's
    # members in one part), rebuilt with one more level's strength given each time
    C, keep = cut(pyamg.strength.symmetric_strength_of_connection(A, 0.0), part)
    cut_fine = field == "displacement"  # the potential lives in one body (the cradle)
    assert (~keep).any() == cut_fine
    strength, parts, cut_coarse = [("predefined", {"C": C})], [part], False
    kw = {} if nn is None else {"B": nn}
    while True:
        ref = pyamg.smoothed_aggregation_solver(
            A, max_coarse=500, coarse_solver="splu", smooth=amg.SMOOTH, keep=True,
            strength=strength + ["symmetric"] * (amg.MAX_LEVELS - len(strength)), **kw,
        )  # fmt: skip
        if len(ref.levels) - 1 == len(strength):
            break
        agg = sp.coo_matrix(ref.levels[len(strength) - 1].AggOp)
        p = np.empty(agg.shape[1], dtype=part.dtype)
        p[agg.col] = parts[-1][agg.row]
        C, keep = cut(
            pyamg.strength.symmetric_strength_of_connection(ref.levels[len(strength)].A, 0.0), p
        )
        cut_coarse |= bool((~keep).any())
        strength.append(("predefined", {"C": C}))
        parts.append(p)
    assert cut_coarse == cut_fine  # the coarser levels of the glued bodies connect them
    r = np.random.default_rng(0).standard_normal(A.shape[0])

    def cycle(ml):
        return ml.solve(r, x0=np.zeros_like(r), tol=0.0, maxiter=1, cycle="W")

    x_ref = cycle(ref)
    ml = amg.smoothed_aggregation(A, nn, part)
    assert len(ml.levels) == len(ref.levels) >= 3
    for a, b in zip(ml.levels, ref.levels, strict=True):
        assert a.A.shape == b.A.shape
        scale = abs(b.A).max()
        assert abs(sp.csr_matrix(a.A) - sp.csr_matrix(b.A)).max() <= 1e-12 * scale
    assert np.linalg.norm(cycle(ml) - x_ref) <= 1e-12 * np.linalg.norm(x_ref)
    if cut_fine:
        ml = amg.smoothed_aggregation(A, nn, None)
        assert np.linalg.norm(cycle(ml) - x_ref) > 1e-6 * np.linalg.norm(x_ref)
        with monkeypatch.context() as m:  # the coarser levels not cut
            m.setattr(amg, "coarse_parts", lambda AggOp, part: None)
            ml = amg.smoothed_aggregation(A, nn, part)
        assert np.linalg.norm(cycle(ml) - x_ref) > 1e-6 * np.linalg.norm(x_ref)
    monkeypatch.setattr(amg, "SMOOTH", ("energy", {**amg.SMOOTH[1], "maxiter": 1}))
    ml = amg.smoothed_aggregation(A, nn, part)
    assert np.linalg.norm(cycle(ml) - x_ref) > 1e-6 * np.linalg.norm(x_ref)
    monkeypatch.setattr(amg, "SMOOTH", ("energy", {**amg.SMOOTH[1], "maxiter": 1}))
    ml = amg.smoothed_aggregation(A, nn, part)
    assert np.linalg.norm(cycle(ml) - x_ref) > 1e-6 * np.linalg.norm(x_ref)
