"""Structured rectangle meshes and uniform refinement."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fem import meshing
from fem.mesh import Mesh
from fem.meshing import rectangle, refine

ELEMENTS = ["quad", "triangle"]
SIDES = ["bottom", "right", "top", "left"]


def signed_areas(mesh: Mesh) -> np.ndarray:
    """Shoelace formula per cell: positive for counterclockwise cells."""
    P = mesh.points[mesh.cells]  # (n_cells, k, 2)
    Q = np.roll(P, -1, axis=1)  # (n_cells, k, 2)
    return 0.5 * (P[..., 0] * Q[..., 1] - Q[..., 0] * P[..., 1]).sum(axis=1)


def part_length(mesh: Mesh, name: str) -> float:
    e = mesh.boundaries[name]
    return float(np.linalg.norm(mesh.points[e[:, 1]] - mesh.points[e[:, 0]], axis=1).sum())


def directed_cell_edges(mesh: Mesh) -> set[tuple[int, int]]:
    c = mesh.cells
    return set(zip(c.ravel().tolist(), np.roll(c, -1, axis=1).ravel().tolist(), strict=True))


def check_mesh(mesh: Mesh) -> None:
    """Cells ccw; boundary parts ordered chains, domain on the left, covering ∂Ω exactly."""
    assert (signed_areas(mesh) > 0).all()
    cell_edges = directed_cell_edges(mesh)
    all_bnd = []
    for name, e in mesh.boundaries.items():
        assert (e[1:, 0] == e[:-1, 1]).all(), f"{name} edges not ordered along the part"
        directed = set(map(tuple, e.tolist()))
        # the cell having (a, b) as a ccw edge lies on the left of (a, b)
        assert directed <= cell_edges, f"{name} has the domain on its right"
        all_bnd += [tuple(sorted(p)) for p in e.tolist()]
    undirected = [tuple(sorted(p)) for p in cell_edges]
    vals, counts = np.unique(np.array(undirected), axis=0, return_counts=True)
    outer = set(map(tuple, vals[counts == 1].tolist()))
    assert sorted(all_bnd) == sorted(outer)


@pytest.mark.parametrize("element", ELEMENTS)
def test_rectangle(element):
    mesh = rectangle((-1.0, 2.0), (0.5, 1.5), (3, 2), element)
    k = 4 if element == "quad" else 3
    assert mesh.cell_type == element
    assert mesh.cells.shape == (6 * (1 if k == 4 else 2), k)
    assert mesh.n_nodes == 12
    assert np.isclose(signed_areas(mesh).sum(), 3.0)
    assert set(mesh.boundaries) == set(SIDES)
    check_mesh(mesh)
    for name, length, n_edges in [("bottom", 3, 3), ("right", 1, 2), ("top", 3, 3), ("left", 1, 2)]:
        assert np.isclose(part_length(mesh, name), length)
        assert len(mesh.boundaries[name]) == n_edges
    assert np.allclose(mesh.points[mesh.boundaries["bottom"][0, 0]], [-1.0, 0.5])
    assert np.allclose(mesh.points[mesh.boundaries["right"][0, 0]], [2.0, 0.5])
    assert np.allclose(mesh.points[mesh.boundaries["top"][0, 0]], [2.0, 1.5])
    assert np.allclose(mesh.points[mesh.boundaries["left"][0, 0]], [-1.0, 1.5])


@pytest.mark.parametrize(
    "args",
    [
        ((0, 1), (0, 1), (0, 2), "quad"),
        ((0, 1), (0, 1), (2, -1), "quad"),
        ((0, 1), (0, 1), (1.5, 2), "quad"),
        ((1, 1), (0, 1), (2, 2), "quad"),
        ((0, 1), (2, 1), (2, 2), "triangle"),
        ((0, 1), (0, 1), (2, 2), "hexagon"),
    ],
)
def test_rectangle_bad_input(args):
    with pytest.raises(ValueError):
        rectangle(*args)


@pytest.mark.parametrize("element", ELEMENTS)
def test_refine(element):
    rng = np.random.default_rng(0)
    coarse = rectangle((0.0, 2.0), (-1.0, 0.5), (3, 2), element)
    # a distorted coarse mesh: refinement must preserve areas of arbitrary convex cells
    pts = coarse.points.copy()
    interior = np.setdiff1d(
        np.arange(coarse.n_nodes), np.unique(np.concatenate(list(coarse.boundaries.values())))
    )
    pts[interior] += rng.uniform(-0.15, 0.15, (interior.size, 2))
    coarse = Mesh(pts, coarse.cells, coarse.boundaries)
    mesh = coarse
    for level in range(1, 4):
        fine = refine(mesh)
        assert fine.n_cells == 4 * mesh.n_cells == 4**level * coarse.n_cells
        assert fine.cell_type == element
        assert np.isclose(signed_areas(fine).sum(), 3.0)
        assert list(fine.boundaries) == list(coarse.boundaries)
        for name in coarse.boundaries:
            assert len(fine.boundaries[name]) == 2 * len(mesh.boundaries[name])
            assert np.isclose(part_length(fine, name), part_length(coarse, name))
            # same endpoints in the same order
            assert fine.boundaries[name][0, 0] == coarse.boundaries[name][0, 0]
            assert fine.boundaries[name][-1, 1] == coarse.boundaries[name][-1, 1]
        check_mesh(fine)
        # nested: parent nodes keep their indices; no duplicate nodes
        assert np.array_equal(fine.points[: mesh.n_nodes], mesh.points)
        assert np.unique(fine.points.round(12), axis=0).shape[0] == fine.n_nodes
        mesh = fine
    assert np.isclose(mesh.h, coarse.h / 8, rtol=0.3)


@pytest.mark.parametrize("element", ELEMENTS)
def test_refine_matches_structured_mesh(element):
    """Refining an nx×ny quad rectangle gives the 2nx×2ny node set (and node count)."""
    fine = refine(rectangle((0, 1), (0, 2), (2, 3), element), times=2)
    direct = rectangle((0, 1), (0, 2), (8, 12), element)
    assert fine.n_nodes == direct.n_nodes
    a = fine.points[np.lexsort(fine.points.T)]
    b = direct.points[np.lexsort(direct.points.T)]
    assert np.allclose(a, b)


def test_refine_times():
    mesh = rectangle((0, 1), (0, 1), (1, 1))
    assert refine(mesh, 0) is mesh
    with pytest.raises(ValueError):
        refine(mesh, -1)


@given(
    c=st.floats(0.0, 1.0),
    p=st.floats(1.0, 4.0),
    n=st.integers(2, 40),
)
def test_graded_keeps_ends_and_focus_and_is_monotone(c, p, n):
    t = np.linspace(0.0, 1.0, n + 1)
    x = meshing.graded(t, 0.0, 1.0, c, p)
    assert x[0] == 0.0 and x[-1] == pytest.approx(1.0, abs=1e-15)
    assert (np.diff(x) > 0).all()
    assert meshing.graded(np.array([c]), 0.0, 1.0, c, p)[0] == c
    assert np.array_equal(meshing.graded(t, 0.0, 1.0, c, 1.0), t)


def test_graded_rectangle_levels_are_nested_and_finer_at_the_focus():
    coarse = meshing.rectangle((-1, 1), (0, 1), (8, 4), focus=(0.0, 1.0), grading=(2.0, 1.5))
    fine = meshing.rectangle((-1, 1), (0, 1), (16, 8), focus=(0.0, 1.0), grading=(2.0, 1.5))
    fine_set = {tuple(np.round(p, 14)) for p in fine.points}
    assert all(tuple(np.round(p, 14)) in fine_set for p in coarse.points)
    x = np.unique(coarse.points[:, 0])
    dx = np.diff(x)
    assert dx[len(dx) // 2] < dx[0] / 4  # cells at x = 0 much narrower than at the ends
    with pytest.raises(ValueError, match="focus"):
        meshing.rectangle((0, 1), (0, 1), (2, 2), focus=(2.0, 0.5), grading=(2.0, 2.0))
