"""benchmarks/zone_marks.py: the candidate contact-zone markings for Hertz."""

from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks import zone_marks as zm
from fem.bisection import prepared, refine_marked
from problems import pipeline
from problems.pipeline import adaptive
from problems.plugins.contact.bodies import given_meshes
from problems.plugins.contract import solve_model


@pytest.fixture(scope="module")
def hertz():
    """hertz level 0 split into triangles, refined twice, solved: (model, solution, meshes)."""
    loaded = pipeline.load("hertz")
    mesh = prepared(loaded.plugin.build(loaded.scene, 0).bodies[0].mesh)
    for _ in range(2):
        mesh = refine_marked(mesh, np.ones(mesh.n_cells, dtype=bool))[0]
    with given_meshes({"body": mesh}):
        model = loaded.plugin.build(loaded.scene, 0)
    sol = solve_model(loaded.plugin, model, method="ssn", tol=1e-10)
    return model, sol, {"body": mesh}


@pytest.mark.parametrize("seed", range(5))
def test_graded_chain_restores_the_grading(seed):
    """A chain graded to 2 with random segments halved is graded to 2 again after the
    closure, which only adds marks; a mutation that keeps the smaller of a pair fails."""
    rng = np.random.default_rng(seed)
    h = np.cumprod(rng.choice([0.5, 1.0, 2.0], size=40))  # (40,) neighbours within 2×
    halved = rng.random(40) < 0.3
    pairs = np.stack([np.arange(39), np.arange(1, 40)], axis=1)
    out = zm.graded_chain(h, halved, pairs)
    s = np.where(out, h / 2, h)
    assert (out >= halved).all()
    assert (np.maximum(s[:-1], s[1:]) <= 2 * np.minimum(s[:-1], s[1:]) * (1 + 1e-9)).all()
    assert not zm.graded_chain(h, np.zeros(40, dtype=bool), pairs).any()


def test_graded_chain_example():
    """[1, 1, 4] with the first halved: 4 against 1 breaks the grading, so the last is
    halved (2 against 1), and nothing else."""
    out = zm.graded_chain(
        np.array([1.0, 1.0, 4.0]), np.array([True, False, False]), [[0, 1], [1, 2]]
    )
    assert out.tolist() == [True, False, True]


def _surface_x(model, mesh, cells):
    """x of the contact-surface nodes that are vertices of the marked cells."""
    c = model.contact
    on = np.isin(c.tr.nodes, mesh.cells[cells].ravel())
    return c.tr.points[on, 0]


def test_edge_marks_the_zone_edge_not_its_centre(hertz):
    """ "edge": the last touching and first open nodes on both sides are vertices of marked
    cells, the centre x = 0 is not; "edge_peak" adds the centre (λ_n is largest there)."""
    model, sol, meshes = hertz
    c = model.contact
    none = {"body": np.zeros(meshes["body"].n_cells, dtype=bool)}
    touch = zm._touch(model, sol)
    x = c.tr.points[:, 0]
    edges = [x[touch].min(), x[touch].max()]
    edges += [x[~touch & (x < edges[0])].max(), x[~touch & (x > edges[1])].min()]
    got = _surface_x(model, meshes["body"], zm.MARKS["edge"](model, sol, meshes, none)["body"])
    assert np.isin(edges, got).all() and 0.0 not in got
    got = zm.MARKS["edge_peak"](model, sol, meshes, none)["body"]
    assert 0.0 in _surface_x(model, meshes["body"], got)


def test_multiplier_indicators(hertz):
    """ "rough" vanishes for a nodal λ_n linear in x (on the graded, unequal segments: a
    swapped h_l, h_r would not), not for a quadratic; "jump" vanishes for a constant λ_n
    (the dual functions sum to one), not for a linear one."""
    model, _, meshes = hertz
    c = model.contact
    x = c.tr.points[c.rows_n, 0]

    def eta2(values, kind):
        lam = np.zeros(c.B_full.shape[0])
        lam[c.idx_n] = values
        return zm.multiplier_indicator(model, SimpleNamespace(lam=lam), meshes, kind)

    scale = eta2(1e6 * x**2, "rough").max()
    assert scale > 0 and eta2(1e6 * (1 + x), "rough").max() < 1e-12 * scale
    scale = eta2(1e6 * x, "jump").max()
    assert scale > 0 and eta2(np.full(x.size, 1e6), "jump").max() < 1e-12 * scale


@pytest.mark.parametrize("name", ["fan_red", "surface_red", "layers3"])
def test_red_zone_cells_are_split_only_red(hertz, name):
    """One marked cell at the centre of the zone: after the marking, the conformity closure
    of the marks splits no cell of the zone that is not marked (so split red); the marks
    grew from the one cell (a mutation stopping after one pass leaves a zone cell split by
    bisection; "layers3" with its rings dropped leaves a cell of the third ring)."""
    from fem.bisection import _closure, _edge_cells, _edges

    model, sol, meshes = hertz
    mesh = meshes["body"]
    c = model.contact
    start = np.zeros(mesh.n_cells, dtype=bool)
    start[
        np.flatnonzero(zm._cells_at(mesh, c.tr.nodes[np.argmin(np.abs(c.tr.points[:, 0]))]))[0]
    ] = True
    m = zm.MARKS[name](model, sol, meshes, {"body": start})["body"]
    codes, cell_edges = _edges(mesh.cells, mesh.n_nodes)
    edges = np.zeros(codes.size, dtype=bool)
    edges[cell_edges[m].ravel()] = True
    split = _closure(cell_edges, _edge_cells(cell_edges, codes.size), edges)[cell_edges].any(axis=1)
    touch = zm._touch(model, sol)
    zone = zm._cells_at(mesh, c.tr.nodes[touch])
    if name == "layers3":
        near = np.zeros(mesh.n_nodes, dtype=bool)
        near[c.tr.nodes[touch]] = True
        for _ in range(3):
            near[mesh.cells[near[mesh.cells].any(axis=1)].ravel()] = True
        zone = near[mesh.cells].any(axis=1)
    if name == "surface_red":
        zone = np.zeros(mesh.n_cells, dtype=bool)
        zone[zm.facet_cells(mesh, c.tr.nodes[c.tr.facets[touch[c.tr.facets].any(axis=1)]])] = True
    assert (m >= start).all() and m.sum() > 1
    assert not (split & zone & ~m).any()


@pytest.mark.parametrize("goal", ["p0", "a"])
def test_dual_solution_represents_its_goal(hertz, goal):
    """The dual solution of the goal-oriented candidates reproduces the goal's value through
    the data, j·λ_h = f·z + gap·μ (A symmetric, B_R u_h = gap on the touching rows); for
    "p0", j·λ_h is λ_n at the centre node, for "a" it is 0. A dual with the constraint
    block dropped or transposed wrongly (−B_Rᵀ) breaks the identity."""
    model, sol, _ = hertz
    z, mu, j = zm.dual_solution(model, sol, goal)
    vi = model.vi
    gap = np.zeros(vi.B.shape[0]) if vi.gap is None else np.asarray(vi.gap)
    lhs, fz, gm = j @ sol.lam, vi.f @ z, gap @ mu
    scale = max(abs(fz), abs(gm))  # "a": j ⟂ λ_h (J'(λ_h)·λ_h = 0), the two terms cancel
    assert scale > 0 and abs(fz + gm - lhs) <= 1e-7 * scale
    if goal == "p0":
        c = model.contact
        x = c.tr.points[c.rows_n, 0]
        assert lhs == pytest.approx(c.normal(sol.lam)[np.argmin(np.abs(x))], rel=1e-12)


def test_dual_indicators_locate_their_goal(hertz):
    """The peak pressure's dual indicator is largest in a cell at the centre node; the
    half-width's in the outer half of the zone (its weight x² − J grows to the edge)."""
    model, sol, meshes = hertz
    mesh, c = meshes["body"], model.contact
    centre = c.tr.nodes[np.argmin(np.abs(c.tr.points[:, 0]))]
    assert centre in mesh.cells[np.argmax(zm.dual_indicators(model, sol, "p0"))]
    touch = zm._touch(model, sol)
    half = np.abs(c.tr.points[touch, 0]).max()
    x = mesh.points[mesh.cells].mean(axis=1)[:, 0]  # (n_cells,)
    assert abs(x[np.argmax(zm.dual_indicators(model, sol, "a"))]) > 0.5 * half


@pytest.mark.parametrize("name", ["peak_red", "near_level", "dual_red", "zone_weighted"])
def test_red_fan_marks_split_the_centre_fan_red(hertz, name):
    """One marked cell at the centre node: these candidates keep it, add marks,
    and mark the centre node's whole fan (split red: each puts red fans there; "near_level"
    marks the near field too)."""
    model, sol, meshes = hertz
    mesh, c = meshes["body"], model.contact
    centre = c.tr.nodes[np.argmin(np.abs(c.tr.points[:, 0]))]
    fan = (mesh.cells == centre).any(axis=1)  # (n_cells,)
    start = np.zeros(mesh.n_cells, dtype=bool)
    start[np.flatnonzero(fan)[0]] = True
    m = zm.MARKS[name](model, sol, meshes, {"body": start})["body"]
    assert (m >= start).all() and m[fan].all()


def test_near_box_marks_the_coarse_box_cells_and_nothing_deeper(hertz):
    """ "near_box" (factor 1) from no marks: outside the red layers' vertex rings, a cell of
    its box is marked exactly when it is coarser than the zone's median segment ×
    2^max(0, (t − 1.3) / 0.5) (t its depth in zone half-lengths; a box without the grading
    fails it), and no cell deeper than the box is."""
    model, sol, meshes = hertz
    mesh, c = meshes["body"], model.contact
    none = {"body": np.zeros(mesh.n_cells, dtype=bool)}
    m = zm.near_box(model, sol, meshes, none, factor=1.0)["body"]
    touch = zm._touch(model, sol)
    p = mesh.points[c.tr.nodes[touch]]
    half, xc = 0.5 * np.ptp(p[:, 0]), 0.5 * (p[:, 0].max() + p[:, 0].min())
    h_zone = np.median(c.tr.measures[touch[c.tr.facets].all(axis=1)])
    P = mesh.points[mesh.cells]
    h = np.linalg.norm(P - np.roll(P, 1, axis=1), axis=-1).max(axis=1)
    cen = P.mean(axis=1)
    t = (p[:, 1].max() - cen[:, 1]) / half
    box = (np.abs(cen[:, 0] - xc) < 1.3 * half) & (t < 2.6)
    coarse = h > h_zone * 2.0 ** np.maximum(0.0, (t - 1.3) / 0.5)
    near = np.zeros(mesh.n_nodes, dtype=bool)
    near[c.tr.nodes[touch]] = True
    for _ in range(3):
        near[mesh.cells[near[mesh.cells].any(axis=1)].ravel()] = True
    layers = near[mesh.cells].any(axis=1)  # the red layers may add marks there
    assert (box & coarse).any() and (box & ~coarse & ~layers).any()
    assert (m[box & ~layers] == coarse[box & ~layers]).all()
    deep = (t > 2.6) & ~layers
    assert deep.any() and not m[deep].any()


NEW = [
    "near_box_f2r2",
    "near_box_tight",
    "near_box_paced",
    "size_graded",
    "box_dorfler30",
    "box_dorfler60",
    "near_box_nvb",
]


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("name", NEW)
def test_new_marks_keep_the_energy_marks_and_the_mesh_conforming(hertz, name, seed):
    """Random Dörfler-like marks (seeded): the candidate's marks contain them, add to them,
    and the refined mesh is conforming (`check_conforming`). A candidate that returns its own
    marks without the energy's (`coarse` instead of `marked | coarse`) fails the first."""
    from tests.fem.test_bisection import check_conforming

    model, sol, meshes = hertz
    mesh = meshes["body"]
    rng = np.random.default_rng(seed)
    start = rng.random(mesh.n_cells) < 0.05
    if name == "near_box_paced":
        zm.MARKS[name].size = None  # a fresh run
    m = zm.MARKS[name](model, sol, meshes, {"body": start})["body"]
    red, once = adaptive.split_marks(m)
    assert m.shape == (mesh.n_cells,) and (once is None) == (name != "near_box_nvb")
    assert (red >= start).all() and red.sum() + (0 if once is None else once.sum()) > start.sum()
    check_conforming(refine_marked(mesh, red, bisect=once)[0], mesh)


@pytest.mark.parametrize("seed", range(5))
def test_zone_distance_is_the_distance_to_the_surface_segment(seed):
    """`zone_distance` against a brute-force minimum over 20,001 points of the segment
    |x − x_c| ≤ ℓ, y = y_top, for random cells (seeded); dropping the max(0, ·) of the
    lateral offset (the distance to the line through the segment's centre) fails."""
    rng = np.random.default_rng(seed)
    half, xc, y_top = rng.uniform(0.1, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)
    pts = rng.uniform(-3.0, 3.0, size=(60, 2))
    mesh = SimpleNamespace(points=pts, cells=np.arange(60).reshape(20, 3))
    got = zm.zone_distance(mesh, (half, xc, y_top, 0.0))
    c = pts[mesh.cells].mean(axis=1)  # (20, 2)
    s = np.stack([np.linspace(xc - half, xc + half, 20_001), np.full(20_001, y_top)], axis=1)
    want = np.linalg.norm(c[:, None] - s[None], axis=-1).min(axis=1) / half
    assert np.allclose(got, want, atol=1e-4)  # the sampling step is 1e-4 ℓ


def test_size_graded_marks_exactly_the_cells_coarser_than_the_size_function(hertz):
    """ "size_graded" from no marks: outside the red layers' vertex rings a cell is marked
    exactly when its longest edge exceeds 2 × the median segment × 2^max(0, (d − 1.3) / 0.5),
    d its centroid's distance to the zone's surface in ℓ; there are cells of both kinds. A
    size function without the grading (or with d measured from the zone's centre) fails."""
    model, sol, meshes = hertz
    mesh, c = meshes["body"], model.contact
    none = {"body": np.zeros(mesh.n_cells, dtype=bool)}
    m = zm.size_graded(model, sol, meshes, none)["body"]
    touch = zm._touch(model, sol)
    p = mesh.points[c.tr.nodes[touch]]
    half, xc = 0.5 * np.ptp(p[:, 0]), 0.5 * (p[:, 0].max() + p[:, 0].min())
    h_zone = np.median(c.tr.measures[touch[c.tr.facets].all(axis=1)])
    P = mesh.points[mesh.cells]
    h = np.linalg.norm(P - np.roll(P, 1, axis=1), axis=-1).max(axis=1)
    cen = P.mean(axis=1)
    d = np.hypot(np.maximum(0, np.abs(cen[:, 0] - xc) - half), p[:, 1].max() - cen[:, 1]) / half
    coarse = h > 2 * h_zone * 2.0 ** np.maximum(0.0, (d - 1.3) / 0.5)
    near = np.zeros(mesh.n_nodes, dtype=bool)
    near[c.tr.nodes[touch]] = True
    for _ in range(3):
        near[mesh.cells[near[mesh.cells].any(axis=1)].ravel()] = True
    out = ~near[mesh.cells].any(axis=1)
    assert (out & coarse).any() and (out & ~coarse).any()
    assert (m[out] == coarse[out]).all()


def test_near_box_paced_target_falls_at_most_by_its_rate(hertz):
    """ "near_box_paced": with no target kept it marks as "near_box"; with a kept target S
    (from a call on a mesh of as many cells) it marks as near_box with factor S / √2 ÷ the
    median segment when that is coarser, and keeps S / √2; a call on a coarser mesh (a new run)
    drops it. Without the pacing (the max) the second call marks as near_box and fails."""
    model, sol, meshes = hertz
    mesh = meshes["body"]
    none = {"body": np.zeros(mesh.n_cells, dtype=bool)}
    paced = zm.NearBoxPaced()
    h_zone = zm._zone_frame(model, sol, mesh)[3]
    first = paced(model, sol, meshes, none)["body"]
    assert (first == zm.near_box(model, sol, meshes, none)["body"]).all()
    assert paced.size == pytest.approx(2 * h_zone)
    paced.size = 8 * h_zone * 2**0.5  # as if the last cycle's target had been that
    second = paced(model, sol, meshes, none)["body"]
    assert paced.size == pytest.approx(8 * h_zone)
    assert (second == zm.near_box(model, sol, meshes, none, factor=8.0)["body"]).all()
    assert (second != first).any()
    paced.n_cells = mesh.n_cells + 1  # the last call's mesh was finer: a new run
    assert (paced(model, sol, meshes, none)["body"] == first).all()


def test_near_box_nvb_bisects_the_box_and_splits_the_rings_red(hertz):
    """ "near_box_nvb" from no marks: near_box's coarse box cells outside the rings are 1
    (bisected once), the cells of the three rings that the bisections' closure would split
    are 2 (split into 4), nothing else is marked; after refining, no cell of the rings is
    split other than red. Dropping the bisections from `red_split`'s closure leaves ring cells
    split by bisection and fails; with one marked cell it is 2 (kept)."""
    from fem.bisection import _closure, _edge_cells, _edges

    model, sol, meshes = hertz
    mesh, c = meshes["body"], model.contact
    none = np.zeros(mesh.n_cells, dtype=bool)
    m = zm.near_box_nvb(model, sol, meshes, {"body": none})["body"]
    frame = zm._zone_frame(model, sol, mesh)
    coarse = zm.box_coarse(mesh, frame, 2.0 * frame[3])
    assert set(np.unique(m)) == {0, 1, 2}
    assert ((m == 1) == (coarse & (m != 2))).all() and not (m[~coarse] == 1).any()
    codes, cell_edges = _edges(mesh.cells, mesh.n_nodes)
    edges = np.zeros(codes.size, dtype=bool)
    edges[cell_edges[m == 2].ravel()] = True
    edges[cell_edges[m == 1, 0]] = True
    split = _closure(cell_edges, _edge_cells(cell_edges, codes.size), edges)[cell_edges].any(1)
    near = np.zeros(mesh.n_nodes, dtype=bool)
    near[c.tr.nodes[zm._touch(model, sol)]] = True
    for _ in range(3):
        near[mesh.cells[near[mesh.cells].any(axis=1)].ravel()] = True
    rings = near[mesh.cells].any(axis=1)
    assert not (rings & (m == 1)).any() and (m[~rings] != 2).all()
    assert (split & rings).any() and not (split & rings & (m != 2)).any()
    one = none.copy()
    one[np.flatnonzero(~rings & ~coarse)[0]] = True
    assert zm.near_box_nvb(model, sol, meshes, {"body": one})["body"][one].tolist() == [2]
