"""Geometry tables of a scene (pydantic sections) → meshes at a refinement level.

Kinds, a union told apart by `kind`: "rectangle" (structured P1/Q1), "half_disc" and "cradle"
(the paper's two bodies as mapped Q1 blocks with boundary nodes on the true arc). Each kind
names its boundary parts (BOUNDARIES, checked against the scene's references before anything
is built). A mesh that would exceed MAX_CELLS cells, or that the mesher refuses (inverted or
degenerate cells), is a SceneError naming the key.
"""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal, get_args

import numpy as np
from pydantic import Field

from fem.boundary import trace
from fem.mesh import Mesh
from fem.meshing import rectangle
from problems.errors import SceneError

from .fields import Cells, Integer, Interval, Number, Point
from .model import UNION_TAGS, Section

MAX_CELLS = 4_000_000  # cells of one body at the requested level (≈ 12M piezo unknowns)


class Rectangle(Section):
    """[x0, x1] × [y0, y1] in nx × ny cells (quads, or each split into two triangles)."""

    BOUNDARIES: ClassVar[tuple[str, ...]] = ("bottom", "right", "top", "left")
    kind: Literal["rectangle"]
    x: Interval
    y: Interval
    cells: Cells
    element: Literal["quad", "triangle"] = "quad"

    def mesh(self, level: int) -> Mesh:
        """The structured mesh at refinement `level` (each level halves the cells' size)."""
        s = 2**level
        nx, ny = self.cells
        _check_size(self, "cells", self.cells, nx * ny * s**2)
        return _meshed(
            self, rectangle, tuple(self.x), tuple(self.y), (nx * s, ny * s), self.element
        )


class _Arc(Section):
    center: Point = [0.0, 1.5]
    radius: Annotated[Number, Field(gt=0.0)] = 1.0
    angle: Annotated[Number, Field(gt=0.0, lt=np.pi)] = np.pi / 2


class HalfDisc(_Arc):
    """The paper's half disc (mapped Q1 blocks, boundary nodes on the true arc)."""

    BOUNDARIES: ClassVar[tuple[str, ...]] = ("contact", "free_left", "free_right", "top")
    kind: Literal["half_disc"]
    n_contact: Annotated[Integer, Field(ge=1)] = 8

    def mesh(self, level: int) -> Mesh:
        """The mesh at refinement `level`."""
        from fem import shapes

        # shapes.half_disc: n_f cells along each free arc, n_r along the spokes (level 0)
        h = self.angle / self.n_contact
        n_f = max(1, round((np.pi / 2 - self.angle / 2) / h))
        n_r = max(1, round(0.5 / h))
        cells = (self.n_contact + 2 * n_f) * n_r + self.n_contact * n_f
        _check_size(self, "n_contact", self.n_contact, cells * 4**level)
        args = (self.center, self.radius, self.angle, self.n_contact, level)
        return _meshed(self, shapes.half_disc, *args)


class Cradle(_Arc):
    """The paper's cradle under the half disc (mapped Q1 blocks)."""

    BOUNDARIES: ClassVar[tuple[str, ...]] = ("bottom", "contact", "left", "right")
    kind: Literal["cradle"]
    n_contact: Annotated[Integer, Field(ge=1)] = 12
    p2: Point = [-1.0, 0.0]
    p3: Point = [1.0, 0.0]

    def mesh(self, level: int) -> Mesh:
        """The mesh at refinement `level`."""
        from fem import shapes

        Cl, Cr = shapes.contact_ends(self.center, self.radius, self.angle)
        height = 0.5 * (np.hypot(*(Cl - self.p2)) + np.hypot(*(Cr - self.p3)))
        n_y = max(1, round(height / (self.radius * self.angle / self.n_contact)))
        _check_size(self, "n_contact", self.n_contact, self.n_contact * n_y * 4**level)
        args = (self.p2, self.p3, self.center, self.radius, self.angle, self.n_contact, level)
        return _meshed(self, shapes.cradle, *args)


# The geometry kinds, told apart by `kind`: add a kind by adding a Section with a `kind`
# literal, BOUNDARIES (None: known only once meshed) and mesh(level) to this union.
Geometry = Annotated[Rectangle | HalfDisc | Cradle, Field(discriminator="kind")]
GEOMETRIES = tuple(
    get_args(c.model_fields["kind"].annotation)[0] for c in get_args(get_args(Geometry)[0])
)
UNION_TAGS.update(("geometry", k) for k in GEOMETRIES)


def _check_size(t: Section, key: str, value, cells: float) -> None:
    if cells > MAX_CELLS:
        raise SceneError(
            t.key(key),
            value,
            f"a mesh of at most {MAX_CELLS:,} cells per body at the requested level "
            f"(this geometry would have about {cells:.3g})",
        )


def _meshed(t: Section, mesher, *args) -> Mesh:
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
                t._path, t.model_dump(), f"a geometry that meshes into valid cells ({err})"
            ) from None
