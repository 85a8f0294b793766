"""Geometry tables of 3D scenes → 3D `fem.mesh.Mesh`es at a refinement level.

Kind "box": [x0, x1] × [y0, y1] × [z0, z1] in nx × ny × nz hexahedra (Q1) or 6 tetrahedra each
(P1), each level halving the cells' size (8 times the cells). Boundary parts "left"/"right"
(x), "front"/"back" (y), "bottom"/"top" (z). An optional `bottom_lift` = h(x, y) curves the
bottom into the surface z = z0 + h(x, y): every node moves up by h(x, y)·(z1 − z)/(z1 − z0)
(nodes on the true surface at every level; the top stays flat); `top_lift` likewise curves the
top (nodes move by h(x, y)·(z − z0)/(z1 − z0)). Kind "extruded": a built-in 2D geometry table
(`section`: rectangle, half_disc or cradle, in the x–y plane) extruded over z in `layers`
layers of hexahedra (`fem.meshing.extrude`; a level refines the section and doubles the
layers); its parts are the section's (surfaces over its curves) and "z0"/"z1" (the ends). A mesh
file, `{ mesh = "part.msh", body = "bracket" }` (no kind): a physical volume group of linear
tetrahedra or hexahedra, its physical surface groups the parts (`problems.scene.imported`). A mesh
of more than MAX_NODES nodes (`geometry.GeometryTable`, counted before meshing), or one the map
inverts, is a SceneError naming the key.
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import Discriminator, Field, Tag

from fem.mesh import Mesh as Mesh3D
from fem.meshing import END_PARTS, box, extrude, transform
from problems.errors import SceneError

from .fields import Integer, Text
from .fields3d import Cells3, Expression3, Interval
from .geometry import Cradle, GeometryTable, HalfDisc, MeshFile, Rectangle
from .imported import file_mesh, imported_mesh3d
from .model import UNION_TAGS


class Box(GeometryTable):
    """A box of hexahedra or tetrahedra, optionally with a curved bottom (`bottom_lift`)."""

    BOUNDARIES: ClassVar[tuple[str, ...]] = ("left", "right", "front", "back", "bottom", "top")
    SIZE_KEY: ClassVar[str] = "cells"
    kind: Literal["box"]
    x: Interval
    y: Interval
    z: Interval
    cells: Cells3
    element: Literal["hexahedron", "tetra"] = "hexahedron"
    bottom_lift: Expression3 | None = None
    top_lift: Expression3 | None = None

    def nodes(self, level: int) -> int:
        """The grid's nodes (tetrahedra split the hexahedra without new nodes)."""
        return int(np.prod([c * 2**level + 1 for c in self.cells]))

    def mesh(self, level: int) -> Mesh3D:
        """The mesh at refinement `level`."""
        self.check_size(level)
        try:
            mesh = box(
                tuple(self.x), tuple(self.y), tuple(self.z), tuple(self.cells), self.element, level
            )
            if self.bottom_lift is not None:
                lift, (z0, z1) = self.bottom_lift, self.z

                def curved(p: np.ndarray) -> np.ndarray:
                    h = lift(p[:, 0], p[:, 1], np.full(len(p), z0))  # (n,)
                    p[:, 2] += h * (z1 - p[:, 2]) / (z1 - z0)
                    return p

                mesh = transform(mesh, curved)
            if self.top_lift is not None:
                top, (z0, z1) = self.top_lift, self.z

                def dished(p: np.ndarray) -> np.ndarray:
                    h = top(p[:, 0], p[:, 1], np.full(len(p), z1))  # (n,)
                    p[:, 2] += h * (p[:, 2] - z0) / (z1 - z0)
                    return p

                mesh = transform(mesh, dished)
        except ValueError as err:
            raise SceneError(
                self._path, self.model_dump(), f"a geometry that meshes into valid cells ({err})"
            ) from None
        return mesh


class Extruded(GeometryTable):
    """A built-in 2D geometry extruded along z in layers of hexahedra (plane-strain scenes)."""

    SIZE_KEY: ClassVar[str] = "layers"
    kind: Literal["extruded"]
    section: Annotated[Rectangle | HalfDisc | Cradle, Field(discriminator="kind")]
    z: Interval
    layers: Annotated[Integer, Field(ge=1)] = 1

    @property
    def BOUNDARIES(self) -> tuple[str, ...]:  # noqa: N802 (the name every geometry has)
        """The section's parts and the two ends."""
        return (*self.section.BOUNDARIES, *END_PARTS)

    def nodes(self, level: int) -> int:
        """The section's nodes times the node layers, layers·2^level + 1."""
        return self.section.nodes(level) * (self.layers * 2**level + 1)

    def mesh(self, level: int) -> Mesh3D:
        """The section's mesh at `level` extruded in layers·2^level layers."""
        self.check_size(level)
        m2 = self.section.mesh(level)
        layers = self.layers * 2**level
        if m2.cells.shape[1] != 4:
            raise SceneError(
                self.key("section"), self.section.model_dump(), "a section of quadrilaterals"
            )
        return extrude(m2, tuple(self.z), layers)


class MeshFile3(MeshFile):
    """`{ mesh = "FILE", body = "GROUP" }`: a 3D mesh file (gmsh .msh or any meshio format) of
    linear tetrahedra or hexahedra, the volume group's cells refined `level` times (each into 8,
    new nodes on the file's faces); its physical surface groups are the boundary parts."""

    body: Text | None = Field(
        None, description="a physical volume group (omitted: every volume cell of the file)"
    )

    def nodes(self, level: int) -> int:
        """The file's mesh's nodes after `level` uniform refinements (each cell into 8)."""
        key = self.key("mesh")
        return file_mesh(self.resolved(), self.body, key, False).refined_nodes(level)

    def mesh(self, level: int) -> Mesh3D:  # type: ignore[override]
        """The body's mesh at refinement `level`."""
        self.check_size(level)
        return imported_mesh3d(self.resolved(), self.body, level, self.key("mesh"))


def _tag(v: Any) -> str | None:
    """The union member of a 3D geometry table: its `kind`, or "mesh" for a file."""
    if isinstance(v, dict):
        if "kind" in v:
            return v["kind"] if isinstance(v["kind"], str) else None
        return "mesh" if "mesh" in v else None
    return "mesh" if isinstance(v, MeshFile3) else getattr(v, "kind", None)


Geometry3 = Annotated[
    Annotated[Box, Tag("box")]
    | Annotated[Extruded, Tag("extruded")]
    | Annotated[MeshFile3, Tag("mesh")],
    Discriminator(
        _tag,
        custom_error_type="geometry",
        custom_error_message="a table with kind = box | extruded, or with mesh = FILE (a 3D "
        "mesh file; and body = GROUP)",
    ),
]
UNION_TAGS.update(("geometry", k) for k in ("box", "extruded"))
