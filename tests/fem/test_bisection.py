"""Newest-vertex bisection (`fem.bisection`) and Dörfler marking (`fem.marking`): conforming,
area-preserving, positively oriented, marked cells refined, angles bounded over cycles, boundary
parts kept, the prolongation exact for linear functions; on structured, graded, imported
(tests/data/user_meshes) and gmsh-made notched meshes; with mutation tests for the closure,
the newest vertex and the boundary split."""

from __future__ import annotations

import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from fem import bisection, marking
from fem.bisection import (
    longest_edge_labelled,
    onto_circle,
    prepared,
    refine_marked,
    split_quads,
)
from fem.marking import dorfler_mark
from fem.mesh import Mesh
from fem.mesh_import import body_mesh, mesh_geo, read_mesh
from fem.meshing import rectangle
from fem.refine import refine
from tests import optional

from .mesh_checks import signed_areas

MESHES = Path(__file__).parents[1] / "data" / "user_meshes" / "meshes"
# (file, body) of the committed user meshes: unstructured, graded, two-body, quads
USER = [
    ("actuator_tri", "actuator"),
    ("actuator_tri", "base"),
    ("actuator_quad", "actuator"),
    ("punch_graded", "punch"),
    ("cylinder_on_block", "cylinder"),
    ("cylinder_on_block", "block"),
]
# A rectangle with a V-notch from the top down to its tip (0, 0.5), the mesh graded towards
# the tip (0.004 there, 0.15 away): gmsh's unstructured triangles.
NOTCH_GEO = """
h = 0.15; ht = 0.004;
Point(1) = {-1, 0, 0, h}; Point(2) = {1, 0, 0, h}; Point(3) = {1, 1, 0, h};
Point(4) = {0.05, 1, 0, h}; Point(5) = {0, 0.5, 0, ht}; Point(6) = {-0.05, 1, 0, h};
Point(7) = {-1, 1, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5}; Line(5) = {5, 6};
Line(6) = {6, 7}; Line(7) = {7, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6, 7}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("sides") = {2, 7};
Physical Curve("top") = {3, 6}; Physical Curve("notch") = {4, 5};
Physical Surface("plate") = {1};
"""


def structured(kind: str) -> Mesh:
    """Structured meshes of [0, 2] × [0, 1]: triangles, quadrilaterals, graded triangles."""
    if kind == "graded":
        return rectangle((0.0, 2.0), (0.0, 1.0), (8, 5), "triangle", (0.5, 1.0), (2.0, 2.0))
    return rectangle((0.0, 2.0), (0.0, 1.0), (6, 4), kind)


@cache
def user_mesh(file: str, body: str) -> Mesh:
    return body_mesh(read_mesh(MESHES / f"{file}.msh"), body)


@pytest.fixture(scope="module")
def notched(tmp_path_factory) -> Mesh:
    optional.gmsh()
    path = tmp_path_factory.mktemp("notch") / "notch.geo"
    path.write_text(NOTCH_GEO)
    return body_mesh(mesh_geo(path, 0), "plate")


def all_meshes(notched_mesh: Mesh | None = None) -> list[Mesh]:
    meshes = [structured(k) for k in ("triangle", "quad", "graded")]
    meshes += [user_mesh(f, b) for f, b in USER]
    return meshes + ([notched_mesh] if notched_mesh is not None else [])


# ---------------------------------------------------------------- independent checks


def edge_counts(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted edges (n_edges, 2) of the cells and the number of cells on each."""
    e = np.sort(cells[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)  # (3 n_cells, 2)
    return np.unique(e, axis=0, return_counts=True)


def exterior_length(mesh: Mesh) -> float:
    edges, count = edge_counts(mesh.cells)
    e = edges[count == 1]
    return float(np.linalg.norm(mesh.points[e[:, 0]] - mesh.points[e[:, 1]], axis=1).sum())


def check_conforming(fine: Mesh, coarse: Mesh) -> None:
    """Every edge in one or two cells, no hanging node: a node inside a cell's edge would leave
    that edge in one cell only, adding to the exterior, whose length must stay the coarse
    mesh's; and no node lies inside an exterior edge."""
    _, count = edge_counts(fine.cells)
    assert count.max() <= 2, "an edge in more than two cells"
    assert np.isclose(exterior_length(fine), exterior_length(coarse), rtol=1e-12), "hanging node"
    edges, count = edge_counts(fine.cells)
    e = edges[count == 1]
    a, b = fine.points[e[:, 0]], fine.points[e[:, 1]]  # (n_ext, 2)
    mids = cKDTree(fine.points).query(0.5 * (a + b))[0]  # a node at an exterior edge's midpoint
    assert (mids > 1e-9 * np.linalg.norm(b - a, axis=1)).all(), "hanging node on the boundary"


def check_boundaries(fine: Mesh, coarse: Mesh) -> None:
    """Same part names; each part split in place: its nodes on the coarse part's polyline, its
    length kept, its chain order kept, the domain on the left of every edge."""
    assert list(fine.boundaries) == list(coarse.boundaries)
    n = np.int64(fine.n_nodes)
    ccw = fine.cells * n + np.roll(fine.cells, -1, axis=1)  # directed cell edges a·n + b
    for name, e in fine.boundaries.items():
        c = coarse.boundaries[name]
        assert np.isin(e[:, 0] * n + e[:, 1], ccw).all(), f"{name}: domain not on the left"
        L = np.linalg.norm(fine.points[e[:, 1]] - fine.points[e[:, 0]], axis=1).sum()
        Lc = np.linalg.norm(coarse.points[c[:, 1]] - coarse.points[c[:, 0]], axis=1).sum()
        assert np.isclose(L, Lc, rtol=1e-12), f"{name}: length changed"
        # the coarse part's nodes appear in the same order along the fine part
        assert np.array_equal(np.intersect1d(e.ravel(), c.ravel()), np.unique(c))
        starts = e[:, 0][np.isin(e[:, 0], c[:, 0])]
        assert np.array_equal(starts, c[:, 0]), f"{name}: order along the part changed"
    edges, count = edge_counts(fine.cells)
    exterior = edges[count == 1] @ [n, 1]  # (n_ext,) codes a·n + b, a < b
    for name, e in fine.boundaries.items():
        assert np.isin(np.sort(e, axis=1) @ [n, 1], exterior).all(), f"{name}: not exterior"


def check_refined(fine: Mesh, coarse: Mesh, marked: np.ndarray) -> None:
    """A marked cell is gone and has a node at the midpoint of each of its edges."""
    tree = cKDTree(fine.points)
    T = coarse.cells[marked]  # (k, 3)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        mid = 0.5 * (coarse.points[T[:, i]] + coarse.points[T[:, j]])
        assert (tree.query(mid)[0] < 1e-12).all(), "a marked cell's edge not bisected"
    n = np.int64(fine.n_nodes)
    kept = np.sort(fine.cells, axis=1) @ [n * n, n, 1]  # (n_cells,) a cell's code
    assert not np.isin(np.sort(T, axis=1) @ [n * n, n, 1], kept).any(), "a marked cell kept"


def check_prolongation(P, fine: Mesh, coarse: Mesh, rng) -> None:
    assert P.shape == (fine.n_nodes, coarse.n_nodes)
    assert np.allclose(np.asarray(P.sum(axis=1)).ravel(), 1.0, atol=1e-13)
    g, c = rng.normal(size=2), rng.normal()
    assert np.allclose(P @ (coarse.points @ g + c), fine.points @ g + c, atol=1e-12)


def check_all(fine: Mesh, P, coarse: Mesh, marked: np.ndarray, rng) -> None:
    assert np.array_equal(fine.points[: coarse.n_nodes], coarse.points), "not nested"
    assert (signed_areas(fine) > 0).all(), "a cell not counterclockwise"
    assert np.isclose(signed_areas(fine).sum(), signed_areas(coarse).sum(), rtol=1e-12)
    check_conforming(fine, coarse)
    check_boundaries(fine, coarse)
    check_refined(fine, coarse, marked)
    check_prolongation(P, fine, coarse, rng)


def min_angle(mesh: Mesh) -> float:
    P = mesh.points[mesh.cells]  # (n_cells, 3, 2)
    u = np.roll(P, -1, axis=1) - P  # (n_cells, 3, 2)
    v = np.roll(P, 1, axis=1) - P
    cos = (u * v).sum(2) / (np.linalg.norm(u, axis=2) * np.linalg.norm(v, axis=2))
    return float(np.arccos(np.clip(cos, -1, 1)).min())


def similarity_floor(mesh: Mesh, depth: int = 6) -> float:
    """The smallest angle among the descendants of each labelled cell under `depth` rounds of
    plain bisection (the definition, written out here independently of `fem.bisection`): NVB's
    descendants of a triangle fall into at most 4 similarity classes, all met by then."""
    T = mesh.points[mesh.cells]  # (n, 3, 2) coordinates, newest vertex first
    floor = np.inf
    for _ in range(depth):
        m = 0.5 * (T[:, 1] + T[:, 2])
        T = np.concatenate([np.stack([m, T[:, 0], T[:, 1]], 1), np.stack([m, T[:, 2], T[:, 0]], 1)])
        u, v = np.roll(T, -1, axis=1) - T, np.roll(T, 1, axis=1) - T
        cos = (u * v).sum(2) / (np.linalg.norm(u, axis=2) * np.linalg.norm(v, axis=2))
        floor = min(floor, float(np.arccos(np.clip(cos, -1, 1)).min()))
    return floor


def local_marks(mesh: Mesh, rng, near: int = 40) -> np.ndarray:
    """Adaptive-like marks: the `near` cells closest to a random cell (repeated, this drives
    deep local refinement with bounded growth), and a few random cells elsewhere."""
    centroids = mesh.points[mesh.cells].mean(axis=1)  # (n_cells, 2)
    focus = centroids[rng.integers(mesh.n_cells)]
    marked = rng.random(mesh.n_cells) < 0.002
    marked[cKDTree(centroids).query(focus, k=min(near, mesh.n_cells))[1]] = True
    return marked


def cycles(mesh: Mesh, rng, n: int, check: bool) -> Mesh:
    """n cycles of `local_marks` and `refine_marked`, each checked (`check_all`) if `check`."""
    for _ in range(n):
        marked = local_marks(mesh, rng)
        fine, P = refine_marked(mesh, marked)
        if check:
            check_all(fine, P, mesh, marked, rng)
        mesh = fine
    return mesh


# ---------------------------------------------------------------- properties


@settings(max_examples=5)
@given(seed=st.integers(0, 2**32 - 1), which=st.integers(0, 8), fraction=st.floats(0.01, 0.5))
def test_random_marks_keep_the_mesh_valid(seed, which, fraction):
    """Random marks on any of the meshes, 2 cycles: nested, counterclockwise, area kept,
    conforming, boundary parts kept, marked cells refined, P exact for linear functions."""
    rng = np.random.default_rng(seed)
    mesh = prepared(all_meshes()[which])
    for _ in range(2):
        marked = rng.random(mesh.n_cells) < fraction
        fine, P = refine_marked(mesh, np.flatnonzero(marked) if rng.random() < 0.5 else marked)
        check_all(fine, P, mesh, marked, rng)
        mesh = fine


def test_notched_gmsh_mesh(notched):
    """gmsh's graded notched plate: 4 checked cycles of local marks."""
    cycles(prepared(notched), np.random.default_rng(4), 4, check=True)


@pytest.mark.parametrize("which", [0, 2, 3, 6])
def test_angles_stay_in_the_similarity_classes(which):
    """10 cycles of local marks: no angle smaller than the smallest angle among the bisection
    descendants of the initial cells (NVB's finitely many similarity classes)."""
    mesh = prepared(all_meshes()[which])
    floor = similarity_floor(mesh)
    fine = cycles(mesh, np.random.default_rng(which), 10, check=False)
    assert fine.n_cells > mesh.n_cells + 1000  # 10 × 40 marked cells, each into 4
    assert min_angle(fine) >= floor - 1e-9


def test_angles_on_the_notched_mesh(notched):
    mesh = prepared(notched)
    fine = cycles(mesh, np.random.default_rng(7), 10, check=False)
    assert min_angle(fine) >= similarity_floor(mesh) - 1e-9


@pytest.mark.slow
@settings(max_examples=25)
@given(seed=st.integers(0, 2**32 - 1), which=st.integers(0, 8))
def test_many_cycles_on_every_mesh(seed, which):
    """The slow tier: 10 checked cycles of local marks, angles bounded, on any mesh."""
    rng = np.random.default_rng(seed)
    mesh = prepared(all_meshes()[which])
    fine = cycles(mesh, rng, 10, check=True)
    assert min_angle(fine) >= similarity_floor(mesh) - 1e-9


@pytest.mark.parametrize("which", range(9))
def test_refining_every_cell_is_uniform_refinement_in_nodes(which):
    """All cells marked: once, exactly the nodes of one uniform refinement (`fem.refine`);
    twice, as many nodes as two uniform refinements; each time 4 cells per cell."""
    coarse = all_meshes()[which]
    mesh = prepared(coarse)
    once, _ = refine_marked(mesh, np.ones(mesh.n_cells, bool))
    uniform = refine(mesh)
    assert np.array_equal(np.sort(once.points, axis=0), np.sort(uniform.points, axis=0))
    twice, _ = refine_marked(once, np.arange(once.n_cells))
    assert twice.n_nodes == refine(mesh, 2).n_nodes == coarse.refined_nodes(2)
    assert twice.n_cells == 16 * mesh.n_cells
    assert np.array_equal(twice.points[: mesh.n_nodes], mesh.points)


def _cell_set(mesh) -> np.ndarray:
    """The cells as sorted rows of their sorted vertex coordinates (numbering-free)."""
    P = np.round(mesh.points[mesh.cells], 12)  # (n_cells, 3, 2)
    P = np.sort(P.view([("x", float), ("y", float)])[..., 0], axis=1)  # (n_cells, 3)
    return np.sort(P.view(float).reshape(len(P), -1), axis=0)


@pytest.mark.parametrize("red", [True, False])
def test_fully_marked_cells_are_split_red(monkeypatch, red):
    """A fully marked cell is split into its four similar triangles at the edge midpoints, as
    uniform refinement does (`fem.refine`): refining every cell gives the same triangles, so a
    structured mesh stays structured (no criss-cross). The mutation: two bisections (bisec3)."""
    if not red:
        bisec3 = lambda tri, mid: (  # noqa: E731 (NVB twice: the pre-red split)
            np.stack([mid[:, 2], mid[:, 0], tri[:, 0]], 1),
            np.stack([mid[:, 2], tri[:, 1], mid[:, 0]], 1),
            np.stack([mid[:, 1], tri[:, 0], mid[:, 0]], 1),
            np.stack([mid[:, 1], mid[:, 0], tri[:, 2]], 1),
        )
        monkeypatch.setattr(bisection, "_red", bisec3)
    mesh = prepared(rectangle((0.0, 2.0), (0.0, 1.0), (6, 4), "triangle"))
    once, P = refine_marked(mesh, np.ones(mesh.n_cells, bool))
    check_all(once, P, mesh, np.ones(mesh.n_cells, bool), np.random.default_rng(0))
    same = np.array_equal(_cell_set(once), _cell_set(refine(mesh)))
    assert same if red else not same


def test_nothing_marked_changes_nothing():
    mesh = prepared(structured("triangle"))
    fine, P = refine_marked(mesh, np.zeros(mesh.n_cells, bool))
    assert np.array_equal(fine.cells, mesh.cells) and np.array_equal(fine.points, mesh.points)
    assert abs(P - np.eye(mesh.n_nodes)).max() == 0


def test_one_marked_cell_makes_a_local_closure():
    """One marked cell in a 12 × 8 grid: split into 4 and closed by a few bisections nearby."""
    mesh = prepared(rectangle((0.0, 1.0), (0.0, 1.0), (12, 8), "triangle"))
    i = mesh.n_cells // 2 + 6
    fine, P = refine_marked(mesh, [i])
    check_all(fine, P, mesh, np.isin(np.arange(mesh.n_cells), [i]), np.random.default_rng(0))
    assert 3 <= fine.n_nodes - mesh.n_nodes <= 8
    assert fine.n_cells - mesh.n_cells <= 16


@pytest.mark.parametrize("seed", range(3))
def test_bisect_cells_are_bisected_once(seed):
    """`bisect` cells (seeded random, no marks): the mesh stays valid (`check_all`), each
    cell's refinement-edge midpoint is a new node, and with every cell of a structured grid
    given, each is split into exactly 2 (the diagonal, shared by a quad's two triangles, is
    both halves' refinement edge): 2 n_cells cells, one node per quad. Ignoring `bisect`
    (the mutation) leaves the mesh unchanged and fails."""
    rng = np.random.default_rng(seed)
    mesh = prepared(rectangle((0.0, 1.0), (0.0, 1.0), (12, 8), "triangle"))
    once = rng.random(mesh.n_cells) < 0.2
    none = np.zeros(mesh.n_cells, dtype=bool)
    fine, P = refine_marked(mesh, none, bisect=once if seed else np.flatnonzero(once))
    check_all(fine, P, mesh, none, rng)
    mid = 0.5 * (mesh.points[mesh.cells[once, 1]] + mesh.points[mesh.cells[once, 2]])
    assert (cKDTree(fine.points).query(mid)[0] < 1e-12).all()
    every, _ = refine_marked(mesh, none, bisect=np.ones(mesh.n_cells, dtype=bool))
    assert every.n_cells == 2 * mesh.n_cells
    assert every.n_nodes == mesh.n_nodes + mesh.n_cells // 2


def test_split_quads_and_labelling():
    """Quads into two counterclockwise triangles with the diagonal as the refinement edge of
    both; longest-edge labelling makes the longest edge the refinement edge."""
    quads = structured("quad")
    tri = split_quads(quads)
    assert tri.n_cells == 2 * quads.n_cells and (signed_areas(tri) > 0).all()
    assert np.isclose(signed_areas(tri).sum(), signed_areas(quads).sum())
    ref = np.sort(tri.cells[:, 1:], axis=1).reshape(-1, 2, 2)  # (n_quads, 2 halves, 2)
    assert np.array_equal(ref[:, 0], ref[:, 1])
    mesh = longest_edge_labelled(user_mesh("punch_graded", "punch"))
    P = mesh.points[mesh.cells]
    L = np.linalg.norm(np.roll(P, -1, axis=1) - P, axis=2)  # (n_cells, 3): 01, 12, 20
    assert np.allclose(L[:, 1], L.max(axis=1))
    assert (signed_areas(mesh) > 0).all()


def test_projection_onto_a_circle():
    """The half disc's arcs: new nodes projected onto the circle; P exact for linear functions
    at the moved nodes (barycentric rows); cells positive; straight parts keep midpoints."""
    from fem.shapes import half_disc

    center, radius = (0.0, 1.5), 1.0
    mesh = prepared(half_disc(center, radius, np.pi / 2, 4, 0))
    area = signed_areas(mesh).sum()
    arcs = ("contact", "free_left", "free_right")
    project = {name: onto_circle(center, radius) for name in arcs}
    rng = np.random.default_rng(3)
    for _ in range(3):
        marked = rng.random(mesh.n_cells) < 0.4
        fine, P = refine_marked(mesh, marked, project)
        new = np.arange(mesh.n_nodes, fine.n_nodes)
        on_arc = np.intersect1d(np.concatenate([fine.boundaries[a] for a in arcs]), new)
        assert on_arc.size > 0
        r = np.linalg.norm(fine.points[on_arc] - center, axis=1)
        assert np.allclose(r, radius, atol=1e-14)
        top = np.intersect1d(fine.boundaries["top"], new)
        assert np.allclose(fine.points[top, 1], mesh.points[mesh.boundaries["top"][0, 0], 1])
        assert (signed_areas(fine) > 0).all()
        assert edge_counts(fine.cells)[1].max() <= 2
        check_prolongation(P, fine, mesh, rng)
        mesh = fine
    assert signed_areas(mesh).sum() > area  # the arcs' new nodes moved outward, onto the circle


def test_two_bodies_refine_each_on_its_own():
    """A two-body file: each body's mesh refined with its own marks; the contact parts of both
    stay on their polylines (a mortar is rebuilt from them by building the model)."""
    rng = np.random.default_rng(5)
    for body in ("cylinder", "block"):
        mesh = prepared(user_mesh("cylinder_on_block", body))
        contact = f"{body}_contact" if body == "cylinder" else "block_top"
        near = np.isin(mesh.cells, mesh.boundaries[contact]).any(axis=1)  # (n_cells,)
        fine, P = refine_marked(mesh, near)
        check_all(fine, P, mesh, near, rng)
        assert len(fine.boundaries[contact]) >= 2 * len(mesh.boundaries[contact])


# ---------------------------------------------------------------- bad input


def test_bad_input_is_refused_clearly():
    mesh = prepared(structured("triangle"))
    with pytest.raises(ValueError, match=r"marked: a bool mask must have shape \(48,\)"):
        refine_marked(mesh, np.ones(5, bool))
    with pytest.raises(ValueError, match=r"marked: cell indices must lie in \[0, 48\)"):
        refine_marked(mesh, [0, 48])
    with pytest.raises(ValueError, match="marked: bool .* or integer cell indices"):
        refine_marked(mesh, [0.5])
    with pytest.raises(ValueError, match="needs a 2D triangle mesh"):
        refine_marked(structured("quad"), [0])
    with pytest.raises(ValueError, match=r"project: unknown boundary part\(s\) \['arc'\]"):
        refine_marked(mesh, [0], {"arc": onto_circle((0, 0), 1)})
    with pytest.raises(ValueError, match="projecting the new boundary nodes: inverted"):
        refine_marked(mesh, [0, 1, 2, 3], {"bottom": lambda p: p + [0.0, 5.0]})
    with pytest.raises(ValueError, match=r"project\['bottom'\] must map points"):
        refine_marked(mesh, [0, 1, 2, 3], {"bottom": lambda p: p[:, :1]})
    with pytest.raises(ValueError, match="split_quads needs a 2D quadrilateral mesh"):
        split_quads(mesh)


# ---------------------------------------------------------------- mutations


def test_mutation_without_the_closure_a_hanging_node_is_detected(monkeypatch):
    monkeypatch.setattr(bisection, "_closure", lambda cell_edges, edge_cells, marked: marked)
    mesh = prepared(structured("triangle"))
    marked = np.isin(np.arange(mesh.n_cells), [20])
    fine, _ = refine_marked(mesh, marked)
    with pytest.raises(AssertionError, match="hanging node"):
        check_conforming(fine, mesh)


def test_mutation_a_wrong_newest_vertex_fails_the_angle_test(monkeypatch):
    """The children stored with an old vertex as their newest one (the same triangles, still
    counterclockwise and conforming): repeated bisection then degenerates."""
    real = refine_marked

    def wrong(mesh, marked):
        fine, P = real(mesh, marked)
        cells = fine.cells.copy()
        child = (cells >= mesh.n_nodes).any(axis=1)  # (n_cells,) cells with a new node
        cells[child] = np.roll(cells[child], 1, axis=1)  # (m, a, b) -> (b, m, a)
        return Mesh(fine.points, cells, fine.boundaries), P

    mesh = prepared(structured("triangle"))
    floor = similarity_floor(mesh)
    monkeypatch.setattr(sys.modules[__name__], "refine_marked", wrong)
    fine = cycles(mesh, np.random.default_rng(0), 10, check=False)
    check_conforming(fine, mesh)  # still a valid mesh: only the angle test sees the fault
    assert min_angle(fine) < floor - 1e-9


def test_mutation_a_dropped_boundary_split_is_detected(monkeypatch):
    monkeypatch.setattr(bisection, "_split_facets", lambda facets, mid: facets)
    mesh = prepared(structured("triangle"))
    marked = np.ones(mesh.n_cells, bool)
    fine, _ = refine_marked(mesh, marked)
    with pytest.raises(AssertionError, match="domain not on the left"):
        check_boundaries(fine, mesh)


def test_mutation_a_dropped_part_is_detected(monkeypatch):
    mesh = prepared(structured("triangle"))
    fine, _ = refine_marked(mesh, [0])
    fewer = Mesh(fine.points, fine.cells, {k: v for k, v in fine.boundaries.items() if k != "top"})
    with pytest.raises(AssertionError):
        check_boundaries(fewer, mesh)


# ---------------------------------------------------------------- Dörfler marking


@settings(max_examples=30)
@given(seed=st.integers(0, 2**32 - 1), theta=st.floats(0.01, 1.0), n=st.integers(1, 300))
def test_dorfler_marks_the_smallest_bulk(seed, theta, n):
    """Σ_M η² ≥ θ Σ η²; no smaller set reaches it (the k − 1 largest do not); M holds the
    largest indicators. Ties and zeros included."""
    rng = np.random.default_rng(seed)
    eta = rng.lognormal(size=n) * (rng.random(n) < 0.8)
    eta[rng.random(n) < 0.2] = eta[0]  # ties
    mask = dorfler_mark(eta, theta)
    total = (eta**2).sum()
    k = int(mask.sum())
    if total == 0:
        assert k == 0
        return
    assert (eta[mask] ** 2).sum() >= theta * total * (1 - 1e-12)
    last = eta[mask].min()
    above = eta > last * (1 + 1e-9)  # the set without the last value's ties
    assert (eta[above] ** 2).sum() < theta * total  # one fewer value does not reach it
    assert mask[eta >= last * (1 - 1e-9)].all()  # every tie of the last value is marked
    if k < n:
        assert eta[mask].min() >= eta[~mask].max()


@pytest.mark.parametrize("tie", [marking.TIE, 0.0])
def test_dorfler_marks_mirror_cells_together(monkeypatch, tie):
    """Indicators in mirror pairs equal to rounding: the pairs are marked together (a symmetric
    problem keeps a symmetric mesh); the mutation TIE = 0 splits a pair at the cut."""
    monkeypatch.setattr(marking, "TIE", tie)
    half = np.array([5.0, 4.0, 3.0, 3.0, 2.0, 1.0])
    eta = np.concatenate([half, half * (1 + 1e-14)])  # (12,) cell i and i + 6 mirror cells
    mask = dorfler_mark(eta, 0.1)  # 25 of 128: one cell of the first pair would do
    together = (mask[:6] == mask[6:]).all()
    assert together if tie else not together


def test_dorfler_edge_cases_and_refusals():
    eta = np.array([0.0, 3.0, 4.0, 0.0])
    assert dorfler_mark(eta, 1.0).tolist() == [False, True, True, False]
    assert dorfler_mark(eta, 0.5).tolist() == [False, False, True, False]  # 16 ≥ 12.5
    assert not dorfler_mark(np.zeros(3), 0.5).any()
    assert dorfler_mark(np.zeros(0), 0.5).shape == (0,)
    with pytest.raises(ValueError, match=r"theta: the bulk fraction must lie in \(0, 1\]"):
        dorfler_mark(eta, 0.0)
    with pytest.raises(ValueError, match="eta: indicators must be finite and >= 0"):
        dorfler_mark(np.array([1.0, -1.0]), 0.5)
    with pytest.raises(ValueError, match=r"eta: one indicator per cell"):
        dorfler_mark(np.ones((2, 2)), 0.5)
