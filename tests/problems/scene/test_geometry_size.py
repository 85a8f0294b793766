"""Every geometry counts its mesh's nodes at a level before meshing (`GeometryTable.nodes`),
exactly; the count caps a body at MAX_NODES, and a command refuses a level range by it before
it solves any level."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fem import mesh, meshing, refine
from problems.commands import resources
from problems.errors import SceneError
from problems.plugins import registry
from problems.scene import geometry, load_scene
from problems.scene.geometry import Box, Cradle, Extruded, HalfDisc, MeshFile, Rectangle

MESHES = Path(__file__).parents[3] / "problems" / "scenes" / "meshes"


def _file(cls, name: str, body: str):
    return cls.model_validate({"mesh": str(MESHES / name), "body": body})


@given(seed=st.integers(0, 2**32 - 1))
def test_the_count_is_the_built_mesh_s_for_every_kind(seed):
    rng = np.random.default_rng(seed)
    angle = float(rng.uniform(0.2, 3.0))
    n = int(rng.integers(1, 12))
    cells2 = [int(c) for c in rng.integers(1, 6, 2)]
    cells3 = [int(c) for c in rng.integers(1, 4, 3)]
    kinds = [
        Rectangle(kind="rectangle", x=[0, 2], y=[0, 1], cells=cells2),
        Rectangle(kind="rectangle", x=[0, 2], y=[0, 1], cells=cells2, element="triangle"),
        HalfDisc(kind="half_disc", angle=angle, n_contact=n),
        Cradle(kind="cradle", angle=angle, n_contact=n),
        Box(kind="box", x=[0, 1], y=[0, 1], z=[0, 1], cells=cells3),
        Box(kind="box", x=[0, 1], y=[0, 1], z=[0, 1], cells=cells3, element="tetra"),
        Extruded(
            kind="extruded",
            section={"kind": "rectangle", "x": [0, 1], "y": [0, 1], "cells": cells2},
            z=[0, 1],
            layers=int(rng.integers(1, 3)),
        ),
    ]
    level = int(rng.integers(0, 3))
    for g in kinds:
        assert g.nodes(level) == g.mesh(level).n_nodes, (g, level)


@pytest.mark.parametrize(
    "g",
    [
        _file(MeshFile, "plate_with_hole.msh", "plate"),
        _file(MeshFile, "bracket3d.msh", "bracket"),
    ],
    ids=["quads from a file", "tetrahedra from a file"],
)
def test_the_count_of_a_file_s_mesh_is_the_refined_mesh_s(g):
    for level in (0, 1, 2):
        assert g.nodes(level) == g.mesh(level).n_nodes


@given(seed=st.integers(0, 2**32 - 1))
def test_refined_nodes_counts_uniform_refinement_of_any_cells(seed):
    """On meshes with holes and several parts (cells of a grid dropped at random), where Euler's
    formula for a disc does not hold: the count uses the mesh's own edges and faces."""
    rng = np.random.default_rng(seed)
    for element in ("quad", "triangle"):
        m = meshing.rectangle((0, 1), (0, 1), tuple(int(c) for c in rng.integers(2, 6, 2)), element)
        keep = rng.random(m.n_cells) < 0.7
        keep[0] = True
        m = type(m)(m.points, m.cells[keep], {})
        for t in (0, 1, 2):
            assert m.refined_nodes(t) == refine.refine(m, t).n_nodes
    for element in ("hexahedron", "tetra"):
        m = meshing.box(
            (0, 1), (0, 1), (0, 1), tuple(int(c) for c in rng.integers(1, 4, 3)), element
        )
        keep = rng.random(m.n_cells) < 0.7
        keep[0] = True
        m = mesh.Mesh(m.points, m.cells[keep], {})
        for t in (0, 1, 2):
            assert m.refined_nodes(t) == refine.refine(m, t).n_nodes


def test_a_level_range_is_refused_by_check_levels_before_it_is_solved(monkeypatch):
    """bracket3d's base has 1,125 tetrahedra: at level 4 about 4.6M cells but 0.84M nodes,
    accepted; with the cap just below the level's count, check_levels (which every command calls
    before solving the range's first level) refuses it naming the mesh key and the file."""
    scene = load_scene("bracket3d")
    plugin = registry.for_scene(scene)
    g = scene.validated(plugin.SCENE_MODEL).bodies["bracket"].geometry
    nodes = g.nodes(4)
    assert nodes < geometry.MAX_NODES  # level 4 is allowed by default
    monkeypatch.setattr(geometry, "MAX_NODES", nodes - 1)
    with pytest.raises(SceneError) as err:
        resources.check_levels(plugin, scene, (0, 4), "--levels", "0..4", force=True)
    assert err.value.key == "bodies.bracket.geometry.mesh"
    assert f"would have {nodes:,} at level 4" in str(err.value)
    assert err.value.file == scene.path
