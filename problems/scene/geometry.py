"""Geometry tables of a scene → meshes: the built-in shapes at a refinement level.

Kinds: "rectangle" (structured P1/Q1), "half_disc" and "cradle" (the paper's two bodies as mapped
Q1 blocks with boundary nodes on the true arc); or a file (`mesh = "FILE"` or `geo = "FILE.geo"`,
`imported`).
A mesh that would exceed MAX_CELLS cells, or that the mesher refuses (inverted or degenerate
cells), is a SceneError naming the key.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fem.boundary import trace
from fem.mesh import Mesh
from fem.meshing import rectangle
from problems.errors import SceneError

from .imported import geo_mesh, imported_mesh, resolve
from .reader import Table

GEOMETRIES = ("rectangle", "half_disc", "cradle")
MAX_CELLS = 4_000_000  # cells of one body at the requested level (≈ 12M piezo unknowns)


def make_mesh(t: Table, level: int, scene_dir: Path | None = None) -> Mesh:
    """The mesh of a `geometry` table at refinement `level`.

    SceneError (naming the geometry key) for a mesh too large to build (more than MAX_CELLS
    cells) or one the mesher refuses: inverted or degenerate cells, zero-length edges.
    `geometry = { mesh = "FILE", body = "GROUP" }` reads a mesh file instead (`imported`;
    FILE relative to `scene_dir`, the scene file's folder).
    """
    if t.has("mesh") or t.has("geo"):
        return _from_file(t, level, scene_dir)
    kind = t.string("kind", choices=GEOMETRIES)
    scale = 2**level
    if kind == "rectangle":
        x0, x1 = t.pair("x")
        y0, y1 = t.pair("y")
        if not x0 < x1:
            raise SceneError(t.key("x"), [x0, x1], "an interval [x0, x1] with x0 < x1")
        if not y0 < y1:
            raise SceneError(t.key("y"), [y0, y1], "an interval [y0, y1] with y0 < y1")
        nx, ny = t.pair("cells", kind=int)
        if nx < 1 or ny < 1:
            raise SceneError(t.key("cells"), [nx, ny], "two positive integers [nx, ny]")
        element = t.string("element", "quad", choices=("quad", "triangle"))
        t.finish()
        _check_size(t, "cells", [nx, ny], nx * ny * scale**2)
        return _meshed(t, rectangle, (x0, x1), (y0, y1), (nx * scale, ny * scale), element)
    from fem import shapes

    center = t.pair("center", [0.0, 1.5])
    radius = t.number("radius", 1.0, lo=0.0, lo_open=True)
    angle = t.number("angle", np.pi / 2, lo=0.0, hi=np.pi, lo_open=True)
    if angle >= np.pi:
        raise SceneError(t.key("angle"), angle, "an opening angle in (0, π)")
    n_contact = t.integer("n_contact", 8 if kind == "half_disc" else 12, lo=1)
    if kind == "half_disc":
        t.finish()
        # shapes.half_disc: n_f cells along each free arc, n_r along the spokes (level 0)
        h = angle / n_contact
        n_f = max(1, round((np.pi / 2 - angle / 2) / h))
        n_r = max(1, round(0.5 / h))
        cells = (n_contact + 2 * n_f) * n_r + n_contact * n_f
        _check_size(t, "n_contact", n_contact, cells * scale**2)
        return _meshed(t, shapes.half_disc, center, radius, angle, n_contact, level)
    p2 = t.pair("p2", [-1.0, 0.0])
    p3 = t.pair("p3", [1.0, 0.0])
    t.finish()
    Cl, Cr = shapes.contact_ends(center, radius, angle)
    height = 0.5 * (np.hypot(*(Cl - p2)) + np.hypot(*(Cr - p3)))
    n_y = max(1, round(height / (radius * angle / n_contact)))
    _check_size(t, "n_contact", n_contact, n_contact * n_y * scale**2)
    return _meshed(t, shapes.cradle, p2, p3, center, radius, angle, n_contact, level)


def _from_file(t: Table, level: int, scene_dir: Path | None) -> Mesh:
    """`geometry = { mesh = "FILE", body = "GROUP" }` (a mesh file, refined on its polylines) or
    `{ geo = "FILE.geo", body = "GROUP" }` (meshed and refined by gmsh onto the geometry)."""
    if t.has("mesh") and t.has("geo"):
        raise SceneError(
            t.key("geo"),
            t.raw("geo"),
            "either mesh (a mesh file) or geo (a gmsh geometry, needs gmsh), not both",
        )
    key = "mesh" if t.has("mesh") else "geo"
    name = t.string(key)
    body = t.raw("body", None)
    if body is not None and not isinstance(body, str):
        raise SceneError(t.key("body"), body, "the name of a physical surface group (a string)")
    t.finish()
    make = imported_mesh if key == "mesh" else geo_mesh
    return make(resolve(scene_dir, name), body, level, t.key(key), MAX_CELLS)


def _check_size(t: Table, key: str, value, cells: float) -> None:
    if cells > MAX_CELLS:
        raise SceneError(
            t.key(key),
            value,
            f"a mesh of at most {MAX_CELLS:,} cells per body at the requested level "
            f"(this geometry would have about {cells:.3g})",
        )


def _meshed(t: Table, mesher, *args) -> Mesh:
    """Call a mesher and trace every boundary part; a ValueError (inverted or degenerate
    cells, zero-length boundary segments) becomes a SceneError naming the geometry."""
    with np.errstate(all="ignore"):
        try:
            mesh = mesher(*args)
            for part in mesh.boundaries:
                trace(mesh, part)
            return mesh
        except ValueError as err:
            raise SceneError(
                t.path, t.data, f"a geometry that meshes into valid cells ({err})"
            ) from None
