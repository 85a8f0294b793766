"""benchmarks/bench_adaptive.py: the Hertz centre diagnostics and the a priori box meshes."""

from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks import bench_adaptive as ba


def _model(x: np.ndarray, lam: np.ndarray) -> SimpleNamespace:
    """A stand-in for a solved contact model: trace nodes at abscissae x (k,), λ_n = lam."""
    k = x.size
    points = np.stack([x, np.ones(k)], axis=1)  # (k, 2)
    contact = SimpleNamespace(
        slave=SimpleNamespace(mesh=SimpleNamespace(points=points)),
        tr=SimpleNamespace(nodes=np.arange(k)),
        rows_n=np.arange(k),
        normal=lambda sol_lam: sol_lam,
    )
    return SimpleNamespace(contact=contact)


@pytest.mark.parametrize("seed", range(4))
def test_centre_reads_the_odd_even_mode(seed):
    """Nodes in random order, λ = p0 (1 − x²) + A (−1)^i at spacing h: the centre node against
    its neighbours' mean is p0 h² + 2A (relative: ÷ p0_ref), h0 = h. Reading neighbours in
    storage order instead of along x fails it."""
    rng = np.random.default_rng(seed)
    h, A, p0 = rng.uniform(0.01, 0.1), rng.uniform(-0.01, 0.01), rng.uniform(1.0, 3.0)
    i = np.arange(-10, 11)
    x, lam = h * i, p0 * (1.0 - (h * i) ** 2) + A * (-1.0) ** i
    perm = rng.permutation(i.size)
    out = ba._centre(_model(x[perm], lam[perm]), SimpleNamespace(lam=lam[perm]), p0)
    assert out["osc"] == pytest.approx((p0 * h**2 + 2 * A) / p0, rel=1e-9, abs=1e-12)
    assert out["h0"] == pytest.approx(h, rel=1e-12)


def test_box_mesh_refines_only_the_box():
    """One box step refines the cells meeting the box, not the far corners: new nodes lie
    within one level-0 cell of the box, and a wider box gives more of them."""
    from problems import pipeline

    loaded = pipeline.load("hertz")
    base = ba.box_mesh(loaded.plugin, loaded.scene, 0, 0, 0.075, 0.12, 0.8)
    narrow = ba.box_mesh(loaded.plugin, loaded.scene, 0, 1, 0.075, 0.12, 0.8)
    wide = ba.box_mesh(loaded.plugin, loaded.scene, 0, 1, 0.5, 0.5, 0.8)
    new = narrow.points[base.n_nodes :]  # (k, 2) the nodes the step added
    assert new.shape[0] > 0
    assert np.abs(new[:, 0]).max() < 0.5 and new[:, 1].min() > 0.5
    assert wide.n_nodes > narrow.n_nodes


def test_zone_marking_parses_names_and_keywords():
    """`--zone SPEC`: a name is its MARKS entry; NAME@KEY=VALUE,... that function with those
    keywords as numbers; an unknown name, a keyword the function does not take (one of the
    four positional arguments the loop passes, or any for a lambda entry) and a value that
    is not a number are refused. Taking every parameter name as a keyword (no [4:]) lets
    "touching@model=1" through and fails."""
    from benchmarks import zone_marks as zm

    assert ba.zone_marking("near_box") is zm.MARKS["near_box"]
    f = ba.zone_marking("near_box@factor=2.4,width=1.1")
    assert f.func is zm.near_box and f.keywords == {"factor": 2.4, "width": 1.1}
    for bad in (
        "nope",
        "nope@factor=1",
        "near_box@size=1",
        "near_box_tight@factor=2",
        "touching@model=1",
        "near_box@factor=x",
        "near_box@factor",
    ):
        with pytest.raises(ValueError):
            ba.zone_marking(bad)


def test_run_passes_the_scene_overrides():
    """`--set` reaches the scene: the bottom pushed up half as far (3 mm, not 6) carries
    roughly half the load at level 0 (the contact is nonlinear: P not exactly halved), and the
    result records the overrides. Dropping `overrides` in `run` leaves P unchanged and fails."""
    half = ['body.displacement=[{boundary = "bottom", value = [0.0, 3.0e-3]}]']
    shipped = ba.run("hertz", 0, 0, zones=())
    halved = ba.run("hertz", 0, 0, zones=(), overrides=tuple(half))
    ratio = halved["uniform"][0]["P"] / shipped["uniform"][0]["P"]
    assert 0.35 < ratio < 0.6
    assert halved["overrides"] == half and shipped["overrides"] == []


def test_hertz_limit_uses_its_box(monkeypatch):
    """`hertz_limit`'s width and depth (--limit-box) are the box of its mesh: 3 uniform steps,
    the zone steps asked for, shrink 0.8; the defaults are the shipped load's box."""
    seen = []

    class Stop(Exception):
        pass

    def record(plugin, scene, *spec):
        seen.append(spec)
        raise Stop

    monkeypatch.setattr(ba, "box_mesh", record)
    for kw in ({}, {"width": 0.05, "depth": 0.08}):
        with pytest.raises(Stop):
            ba.hertz_limit(None, None, 4, **kw)
    assert seen == [(3, 4, 0.075, 0.12, 0.8), (3, 4, 0.05, 0.08, 0.8)]


def test_run_radius_sets_the_gap_and_the_reference():
    """`--radius R`: the scene's gap becomes x²/(2R) (a shallower cylinder at R = 2 carries
    more load at the same push) and the closed form uses R (a_ref² = 4PR/(πE*): a_ref²/P
    doubles). Measuring with the default R instead, or not setting the gap, fails."""
    shipped = ba.run("hertz", 0, 0, zones=())["uniform"][0]
    res = ba.run("hertz", 0, 0, zones=(), radius=2.0)
    wide = res["uniform"][0]
    assert res["overrides"] == ['contact.gap="x**2 / (2 * 2.0)"']
    assert wide["P"] > 1.05 * shipped["P"]
    ratio = (wide["a_ref"] ** 2 / wide["P"]) / (shipped["a_ref"] ** 2 / shipped["P"])
    assert ratio == pytest.approx(2.0, rel=1e-9)
