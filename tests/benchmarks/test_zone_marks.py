"""benchmarks/zone_marks.py: the candidate contact-zone markings of the Hertz third pass."""

from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks import zone_marks as zm
from fem.bisection import prepared, refine_marked
from problems import pipeline
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


@pytest.mark.parametrize("name", ["fan_red", "surface_red"])
def test_red_zone_cells_are_split_only_red(hertz, name):
    """One marked cell at the centre of the zone: after the marking, the conformity closure
    of the marks splits no cell of the zone that is not marked (so split red); the marks
    grew from the one cell (a mutation stopping after one pass leaves a zone cell split by
    bisection)."""
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
    if name == "surface_red":
        zone = np.zeros(mesh.n_cells, dtype=bool)
        zone[zm.facet_cells(mesh, c.tr.nodes[c.tr.facets[touch[c.tr.facets].any(axis=1)]])] = True
    assert (m >= start).all() and m.sum() > 1
    assert not (split & zone & ~m).any()
