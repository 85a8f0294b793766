"""fem.locate: a coarse P1/Q1 field at the nodes of a finer mesh, 2D and 3D."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fem import locate, meshing
from fem.shapes import half_disc

ELEMENTS = ["triangle", "quad", "tetra", "hexahedron"]


def _nested(element: str, graded: bool):
    """(coarse, fine): a coarse mesh of `element` and its uniform refinement; `graded` (2D):
    node lines graded towards a corner, so that the cell with the nearest centroid is not
    always the one that holds a fine node."""
    if element in ("triangle", "quad"):
        kw = {"focus": (0.0, 0.0), "grading": (2.5, 2.5)} if graded else {}
        grid = ((0.0, 1.0), (0.0, 2.0))
        return (
            meshing.rectangle(*grid, (2, 3), element, **kw),
            meshing.rectangle(*grid, (4, 6), element, **kw),
        )
    box = ((0.0, 1.0), (0.0, 2.0), (0.0, 0.5), (2, 3, 1), element)
    return meshing.box(*box, 0), meshing.box(*box, 1)


def _nested_error(element: str, graded: bool) -> float:
    """max |evaluate − expected| over the fine nodes on coarse nodes (the coarse value) and on
    coarse edges (the two values interpolated linearly: P1 and Q1 are linear along edges), for
    random nodal values, so a wrong cell or wrong reference coordinates show."""
    coarse, fine = _nested(element, graded)
    assert (locate.locate(coarse, fine.points)[2] <= locate.OUTSIDE_TOL).all()
    rng = np.random.default_rng(7)
    nodal = rng.standard_normal((coarse.n_nodes, 2))  # (N_c, 2) two components
    vals = locate.evaluate(coarse, nodal, fine.points)  # (N_f, 2)
    expect = np.full((fine.n_nodes, 2), np.nan)
    for i, p in enumerate(coarse.points):
        expect[np.flatnonzero(np.abs(fine.points - p).max(axis=1) < 1e-12)] = nodal[i]
    cells = coarse.cells  # (n_cells, n_loc): the edges of the cell types
    pairs = {tuple(sorted((a, b))) for c in cells for a in c for b in c if a != b}
    simplex = element in ("triangle", "tetra")
    for a, b in pairs:
        if not simplex and np.count_nonzero(coarse.points[a] != coarse.points[b]) != 1:
            continue  # not an edge (quads, hexahedra: the edges are axis-parallel)
        pa, e = coarse.points[a], coarse.points[b] - coarse.points[a]  # (d,) each
        t = (fine.points - pa) @ e / (e @ e)  # (N_f,) the position along the edge
        off = np.abs(fine.points - pa - t[:, None] * e).max(axis=1)  # (N_f,) off its line
        at = np.flatnonzero((off < 1e-12) & (t > 1e-12) & (t < 1 - 1e-12))
        expect[at] = (1 - t[at, None]) * nodal[a] + t[at, None] * nodal[b]  # linear on edges
    known = ~np.isnan(expect[:, 0])
    assert known.sum() > coarse.n_nodes  # coarse nodes and edge midpoints were checked
    return float(np.abs(vals[known] - expect[known]).max())


@pytest.mark.parametrize(
    "element, graded", [(e, False) for e in ELEMENTS] + [("triangle", True), ("quad", True)]
)
def test_nested_nodes_get_the_coarse_values_and_edge_midpoints_their_mean(element, graded):
    """On nested meshes the transfer is the prolongation (`_nested_error`)."""
    assert _nested_error(element, graded) <= 1e-12


def _misplaced(element: str, seed: int) -> int:
    """How many of 200 random points of the (graded, in 2D) coarse mesh `locate` puts in a
    cell that does not hold them: reference coordinates outside the reference cell by more
    than OUTSIDE_TOL (judged here, not by `locate.outside`), or a cell map that does not give
    the point back. (The nearest centroids alone, without `_search_ball`, misplaced a point
    for 111 of 300 seeds on the graded triangles and 5 of 300 on the tetrahedra.)"""
    mesh = _nested(element, graded=True)[0]
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)  # (d,) each: a box domain
    pts = np.random.default_rng(seed).uniform(lo, hi, (200, lo.size))  # (200, d)
    cell, xi, _ = locate.locate(mesh, pts)
    if element in ("triangle", "tetra"):
        out = np.maximum(-xi.min(axis=1), xi.sum(axis=1) - 1)  # (200,)
    else:
        out = np.abs(xi).max(axis=1) - 1  # (200,)
    back = locate.interpolate(mesh, mesh.points, cell, xi)  # (200, d)
    return int(((out > locate.OUTSIDE_TOL) | (np.abs(back - pts).max(axis=1) > 1e-12)).sum())


@pytest.mark.parametrize("element", ELEMENTS)
@given(seed=st.integers(0, 2**32 - 1))
def test_random_points_are_found_in_a_cell_that_holds_them(element, seed):
    assert _misplaced(element, seed) == 0


def test_placement_check_catches_the_nearest_centroids_alone(monkeypatch):
    """Mutation: without the search among every cell that can hold a point (`_search_ball`),
    the 8 nearest centroids miss the cell of a point of the graded triangle mesh (seed 0:
    one point, 0.0025 outside its best candidate), and the check says so."""
    assert _misplaced("triangle", 0) == 0
    monkeypatch.setattr(locate, "_search_ball", lambda *args: None)
    assert _misplaced("triangle", 0) > 0


def test_placement_check_catches_every_point_taken_in_the_nearest_cell(monkeypatch):
    """The check above fails when every point counts as inside the cell with the nearest
    centroid (the search among the other candidates skipped)."""
    monkeypatch.setattr(locate, "outside", lambda cell_type, xi: np.zeros(xi.shape[:-1]) - 1)
    assert _misplaced("quad", 0) > 0
    assert _misplaced("tetra", 0) > 0


@pytest.mark.parametrize("element", ELEMENTS)
def test_a_point_outside_the_mesh_is_found_outside_and_extrapolated(element):
    """A point beyond the unit square / cube lies outside it by more than OUTSIDE_TOL, and an
    affine field (P1/Q1 exact) is extrapolated to it exactly."""
    if element in ("triangle", "quad"):
        coarse = meshing.rectangle((0.0, 1.0), (0.0, 1.0), (1, 1), element)
    else:
        coarse = meshing.box((0.0, 1.0), (0.0, 1.0), (0.0, 1.0), (1, 1, 1), element, 0)
    dim = coarse.points.shape[1]
    pts = np.full((2, dim), 0.5)  # (2, d) inside, outside
    pts[1, 0] = 1.5
    coef = np.array([1.0, 2.0, -3.0])[:dim]
    nodal = coarse.points @ coef  # (N,) an affine field
    assert (locate.locate(coarse, pts)[2] > locate.OUTSIDE_TOL).tolist() == [False, True]
    vals = locate.evaluate(coarse, nodal[:, None], pts)  # (2, 1)
    np.testing.assert_allclose(vals[:, 0], pts @ coef, atol=1e-12)


@pytest.mark.parametrize(
    "mesh", [meshing.rectangle((0, 2), (0, 1), (3, 2), "triangle"), half_disc()]
)
def test_evaluate_reproduces_linear_fields_exactly(mesh):
    """A linear field at points inside cells (convex combinations of a cell's nodes) of a
    triangle mesh and of the curved half disc (mapped quads) is reproduced."""
    lin = lambda p: np.stack([1 + 2 * p[:, 0] - p[:, 1], 3 * p[:, 1]], axis=1)  # noqa: E731
    rng = np.random.default_rng(1)
    cells = rng.integers(0, mesh.n_cells, 200)
    w = rng.dirichlet(np.ones(mesh.cells.shape[1]), 200)  # (200, n_loc) convex weights
    pts = np.einsum("ma,mai->mi", w, mesh.points[mesh.cells[cells]])  # points inside cells
    np.testing.assert_allclose(locate.evaluate(mesh, lin(mesh.points), pts), lin(pts), atol=1e-12)


@given(st.integers(0, 2**32 - 1), st.sampled_from([2, 3]))
def test_small_solves_agree_with_lapack_and_flag_singular_matrices(seed, d):
    """`_solve_small` (Cramer's rule in 2D) against numpy's solve on random matrices; a
    singular matrix (a collapsed candidate cell) gives a row of NaN or inf, which `_invert`
    turns into a point at infinity (outside), never a finite wrong answer."""
    rng = np.random.default_rng(seed)
    J = rng.standard_normal((20, d, d)) + 3.0 * np.eye(d)  # (20, d, d)
    r = rng.standard_normal((20, d))
    J[0] = 0.0  # a cell collapsed to a point
    x = locate._solve_small(J, r)
    assert not np.isfinite(x[0]).any()
    expect = np.linalg.solve(J[1:], r[1:, :, None])[:, :, 0]
    assert np.allclose(x[1:], expect, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("element", ELEMENTS)
@given(seed=st.integers(0, 2**32 - 1))
def test_points_far_from_every_cell_keep_a_candidate_in_any_order(element, seed):
    """Points farther from every centroid than any cell's radius (none within `_search_ball`'s
    reach), mixed in any order with points inside and just outside, each get a valid cell: the
    inside ones a cell that holds them, the far ones the candidate they are least outside of,
    and an affine field is extrapolated to them exactly. (The last point of the search having
    no cell in reach indexed one past the end: IndexError on cylinder_on_block's estimate.)"""
    rng = np.random.default_rng(seed)
    mesh = _nested(element, graded=True)[0]
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)  # (d,) each
    n_far = int(rng.integers(1, 6))
    inside = rng.uniform(lo, hi, (int(rng.integers(0, 20)), lo.size))  # (m, d)
    near = hi + rng.uniform(0.01, 0.2, (int(rng.integers(0, 5)), lo.size))  # just outside
    far = hi + rng.uniform(10.0, 1e3, (n_far, lo.size))  # (n_far, d) beyond every reach
    pts = np.concatenate([inside, near, far])
    perm = rng.permutation(len(pts))
    cell, xi, out = locate.locate(mesh, pts[perm])
    assert ((cell >= 0) & (cell < mesh.n_cells)).all()
    rank = np.argsort(perm)  # position of each original point in pts[perm]
    assert (out[rank[: len(inside)]] <= locate.OUTSIDE_TOL).all()
    assert (out[rank[len(inside) :]] > locate.OUTSIDE_TOL).all()
    coef = np.array([1.0, -2.0, 0.5])[: lo.size]
    vals = locate.evaluate(mesh, (mesh.points @ coef)[:, None], pts)[:, 0]  # (M,)
    np.testing.assert_allclose(vals[:-n_far], (pts @ coef)[:-n_far], atol=1e-12)
    # up to 1e3 cell sizes away the value is a sum of terms of size |coef| |p| that cancel:
    # rounding relative to that size (measured ≤ 3e-9 of it on hexahedra)
    scale = np.abs(coef).sum() * np.abs(pts[-n_far:]).max(axis=1)  # (n_far,)
    assert (np.abs(vals[-n_far:] - (pts @ coef)[-n_far:]) <= 1e-7 * scale).all()


def _distorted_quads(seed: int):
    """A 5 × 4 quadrilateral mesh of the unit square whose interior nodes are moved at random by
    up to 0.3 of a cell (the cells stay convex): bilinear, not affine, cell maps."""
    mesh = meshing.rectangle((0.0, 1.0), (0.0, 1.0), (5, 4), "quad")
    P = mesh.points.copy()
    inner = (P > 1e-12).all(axis=1) & (P < 1 - 1e-12).all(axis=1)
    rng = np.random.default_rng(seed)
    P[inner] += rng.uniform(-0.3, 0.3, (inner.sum(), 2)) * [0.2, 0.25]
    return type(mesh)(P, mesh.cells, mesh.boundaries)


@given(seed=st.integers(0, 2**32 - 1))
def test_points_in_distorted_quads_map_back(seed):
    """Every point of the square is put in a cell whose map gives it back. Newton on a
    bilinear map, started in the cell with the nearest centroid for a point of a neighbour,
    may stop after NEWTON_STEPS inside [-1, 1]² at a point that maps elsewhere: that cell was
    taken (7 % of such inversions on random convex quads), and `evaluate` read the field
    there (a user's graded quad mesh: 2 of ~600 carried values wrong by up to 0.96)."""
    mesh = _distorted_quads(seed)
    pts = np.random.default_rng(seed + 1).uniform(0.0, 1.0, (300, 2))  # (300, 2)
    cell, xi, out = locate.locate(mesh, pts)
    back = locate.interpolate(mesh, mesh.points, cell, xi)  # (300, 2)
    assert (out <= locate.OUTSIDE_TOL).all()
    np.testing.assert_allclose(back, pts, atol=1e-12)


@given(seed=st.integers(0, 2**32 - 1))
def test_an_inversion_taken_as_inside_gives_the_point_back(seed):
    """`_invert` on one random convex quadrilateral and points around it: every result inside
    the reference square maps to its point (the unconverged ones are outside: inf)."""
    rng = np.random.default_rng(seed)
    while True:
        Q = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) + rng.uniform(-0.45, 0.45, (4, 2))
        e = np.roll(Q, -1, axis=0) - Q  # (4, 2) the edges
        if (
            e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
        ).min() > 0.05:
            break  # convex, counterclockwise
    mesh = type(_distorted_quads(0))(Q, np.array([[0, 1, 2, 3]]))
    pts = rng.uniform(-1.5, 2.5, (400, 2))  # (400, 2)
    xi = locate._invert(mesh, pts, np.zeros((400, 1), dtype=np.int64))[:, 0]  # (400, 2)
    inside = locate.outside("quad", xi) <= locate.OUTSIDE_TOL
    back = locate.interpolate(mesh, Q, np.zeros(inside.sum(), dtype=np.int64), xi[inside])
    np.testing.assert_allclose(back, pts[inside], atol=1e-12)


def test_mutation_unconverged_inversions_taken_inside_are_caught(monkeypatch):
    """With the unconverged pairs kept (`_misses` saying none misses), both checks fail."""
    monkeypatch.setattr(locate, "_misses", lambda ref, X, xi, p: np.zeros(len(xi), dtype=bool))
    with pytest.raises(AssertionError):
        test_an_inversion_taken_as_inside_gives_the_point_back()
    with pytest.raises(AssertionError):
        test_points_in_distorted_quads_map_back()
