"""Geometry tables of 2D and 3D scenes (pydantic sections) → meshes at a refinement level.

`Geometry` is the union of every kind, told apart by `kind` (a file by its `mesh` or `geo`
key); each table's DIM (2 or 3; a mesh file's is its cells') is the dimension of the body it
meshes. `PlaneGeometry` takes the 2D ones only (plug-ins whose scenes are 2D).

2D kinds: "rectangle" (structured P1/Q1), "half_disc"
and "cradle" (the paper's two bodies as mapped Q1 blocks with boundary nodes on the true arc);
or a file, `{ mesh = "FILE", body = "GROUP" }` or `{ geo = "FILE.geo", body = "GROUP" }`
(`imported`; the path relative to the scene file). The built-in kinds name their boundary parts
(BOUNDARIES, checked against the scene's references before anything is built); a file's parts
are known only once it is read (BOUNDARIES None: the plug-ins check them after meshing,
`check_meshed`). A mesh that would exceed MAX_NODES nodes, or that the mesher refuses (inverted
or degenerate cells), is a SceneError naming the key. Every geometry counts its nodes at a level
before meshing (`GeometryTable.nodes`, exact), so a command refuses a level range before it
solves the coarser levels (`problems.commands.resources.check_levels`).

3D kinds (3D `fem.mesh.Mesh`es): "box", [x0, x1] × [y0, y1] × [z0, z1] in
nx × ny × nz hexahedra (Q1) or 6 tetrahedra each (P1), each level halving the cells' size; parts
"left"/"right" (x), "front"/"back" (y), "bottom"/"top" (z). An optional `bottom_lift` = h(x, y)
curves the bottom into the surface z = z0 + h(x, y): every node moves up by
h(x, y)·(z1 − z)/(z1 − z0) (nodes on the true surface at every level; the top stays flat);
`top_lift` likewise curves the top (nodes move by h(x, y)·(z − z0)/(z1 − z0)). "extruded": a
built-in 2D geometry table (`section`: rectangle, half_disc or cradle, in the x–y plane)
extruded over z in `layers` layers of hexahedra (`fem.meshing.extrude`; a level refines the
section and doubles the layers); its parts are the section's (surfaces over its curves) and
"z0"/"z1" (the ends). A 3D mesh file, `{ mesh = "part.msh", body = "bracket" }`: a physical
volume group of linear tetrahedra or hexahedra, its physical surface groups the parts.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import reduce
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    BeforeValidator,
    Discriminator,
    Field,
    Tag,
    ValidationInfo,
    model_validator,
)
from pydantic_core import PydanticCustomError

from fem.facets import trace
from fem.mesh import Mesh
from fem.meshing import END_PARTS, box, extrude, rectangle, transform
from problems.errors import SceneError

from .fields import BoxCells, Cells, Expression, Integer, Interval, Number, Pair, Point, Text
from .imported import file_dimension, file_mesh, geo_mesh, imported_mesh, resolve
from .model import UNION_TAGS, Section, refuse


def _grading(v: list) -> list:
    if any(p < 1.0 or p > 4.0 for p in v):
        raise PydanticCustomError("grading", "powers in [1, 4] (1: uniform)")
    return v


Grading = Annotated[Pair, AfterValidator(_grading)]
# nodes of one body at the requested level (2D piezo: 12M unknowns; 3D with a potential: 16M);
# counted in nodes, not cells: a tetrahedral mesh has about 5 cells per node, a quad mesh 1
MAX_NODES = 4_000_000


class GeometryTable(Section):
    """A body's geometry table: `nodes(level)` counts the mesh's nodes at a level without
    meshing; `check_size(level)` refuses more than MAX_NODES, naming SIZE_KEY."""

    SIZE_KEY: ClassVar[str]  # the key that sets the mesh's size, blamed for a refusal
    DIM: ClassVar[int]  # the mesh's dimension (a mesh file: its cells', None if unreadable)

    def nodes(self, level: int) -> int:
        """Nodes of the mesh at refinement `level` (exact), before it is built."""
        raise NotImplementedError

    def size_value(self) -> Any:
        """The value of SIZE_KEY, shown in a refusal."""
        return getattr(self, self.SIZE_KEY)

    def curves(self) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
        """Boundary part name → the projection of points (k, 2) onto the part's true curve, for
        the parts that are curved (a refined mesh puts its new boundary nodes there:
        `fem.bisection.refine_marked`'s `project`); none for straight parts and mesh files."""
        return {}

    def check_size(self, level: int) -> None:
        """SceneError naming SIZE_KEY if the mesh at `level` would exceed MAX_NODES nodes."""
        n = self.nodes(level)
        if n > MAX_NODES:
            raise SceneError(
                self.key(self.SIZE_KEY),
                self.size_value(),
                f"a mesh of at most {MAX_NODES:,} nodes per body at the requested level "
                f"(this geometry would have {n:,} at level {level})",
            )


class Rectangle(GeometryTable):
    """[x0, x1] × [y0, y1] in nx × ny cells (quads, or each split into two triangles),
    optionally graded towards a point (`focus`, powers `grading`: `fem.meshing.graded`)."""

    BOUNDARIES: ClassVar[tuple[str, ...]] = ("bottom", "right", "top", "left")
    SIZE_KEY: ClassVar[str] = "cells"
    DIM: ClassVar[int] = 2
    kind: Literal["rectangle"]
    x: Interval
    y: Interval
    cells: Cells
    element: Literal["quad", "triangle"] = "quad"
    focus: Point | None = Field(
        None, description="a point of the rectangle the node lines are graded towards"
    )
    grading: Grading = Field(
        [1.0, 1.0], description="powers p_x, p_y ≥ 1 of the grading (1: uniform); with focus"
    )

    @model_validator(mode="after")
    def _focus_inside(self) -> Rectangle:
        f = self.focus
        if f is not None and not (
            self.x[0] <= f[0] <= self.x[1] and self.y[0] <= f[1] <= self.y[1]
        ):
            raise refuse(["focus"], f, "a point of the rectangle x × y")
        return self

    def nodes(self, level: int) -> int:
        """(nx·2^level + 1)(ny·2^level + 1) (triangles split the quads without new nodes)."""
        nx, ny = self.cells
        return (nx * 2**level + 1) * (ny * 2**level + 1)

    def mesh(self, level: int) -> Mesh:
        """The structured mesh at refinement `level` (each level halves the cells' size)."""
        self.check_size(level)
        s = 2**level
        nx, ny = self.cells
        focus = None if self.focus is None else tuple(self.focus)
        return _meshed(
            self,
            rectangle,
            tuple(self.x),
            tuple(self.y),
            (nx * s, ny * s),
            self.element,
            focus,
            tuple(self.grading),
        )


class _Arc(GeometryTable):
    SIZE_KEY: ClassVar[str] = "n_contact"
    DIM: ClassVar[int] = 2
    center: Point = [0.0, 1.5]
    radius: Annotated[Number, Field(gt=0.0)] = 1.0
    angle: Annotated[Number, Field(gt=0.0, lt=np.pi)] = np.pi / 2
    ARCS: ClassVar[tuple[str, ...]]  # the parts on the circle

    def curves(self) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
        """The parts on the circle (center, radius) → the projection onto it."""
        from fem.bisection import onto_circle

        return {part: onto_circle(self.center, self.radius) for part in self.ARCS}

    def mesh(self, level: int) -> Mesh:
        """The mesh at refinement `level` (`fem.shapes`' mesher named as the kind)."""
        from fem import shapes

        self.check_size(level)
        return _meshed(self, getattr(shapes, self.kind), *self._args(level))


class HalfDisc(_Arc):
    """The paper's half disc (mapped Q1 blocks, boundary nodes on the true arc)."""

    BOUNDARIES: ClassVar[tuple[str, ...]] = ("contact", "free_left", "free_right", "top")
    ARCS: ClassVar[tuple[str, ...]] = ("contact", "free_left", "free_right")
    kind: Literal["half_disc"]
    n_contact: Annotated[Integer, Field(ge=1)] = 8

    def _args(self, level: int) -> tuple:
        return (self.center, self.radius, self.angle, self.n_contact, level)

    def nodes(self, level: int) -> int:
        """Nodes of `fem.shapes.half_disc`'s four blocks glued into a disc-like mesh: with C
        cells and B boundary edges, V = C + B/2 + 1 (Euler: V − E + C = 1, 4C = 2E − B)."""
        k, h = 2**level, self.angle / self.n_contact
        n_c = self.n_contact * k
        n_f = max(1, round((np.pi / 2 - self.angle / 2) / h)) * k  # cells along a free arc
        n_r = max(1, round(0.5 / h)) * k  # cells along the spokes
        cells = (n_c + 2 * n_f) * n_r + n_c * n_f
        return cells + (n_r + n_c + n_f) + 1  # B/2: half of top 2n_r + n_c, arcs 2n_f + n_c


class Cradle(_Arc):
    """The paper's cradle under the half disc (mapped Q1 blocks)."""

    BOUNDARIES: ClassVar[tuple[str, ...]] = ("bottom", "contact", "left", "right")
    ARCS: ClassVar[tuple[str, ...]] = ("contact",)
    kind: Literal["cradle"]
    n_contact: Annotated[Integer, Field(ge=1)] = 12
    p2: Point = [-1.0, 0.0]
    p3: Point = [1.0, 0.0]

    def _args(self, level: int) -> tuple:
        return (self.p2, self.p3, self.center, self.radius, self.angle, self.n_contact, level)

    def nodes(self, level: int) -> int:
        """(n_c + 1)(n_y + 1): `fem.shapes.cradle` is one block of n_contact·2^level cells
        along the arc and n_y·2^level across."""
        from fem import shapes

        Cl, Cr = shapes.contact_ends(self.center, self.radius, self.angle)
        height = 0.5 * (np.hypot(*(Cl - self.p2)) + np.hypot(*(Cr - self.p3)))
        n_y = max(1, round(height / (self.radius * self.angle / self.n_contact)))
        return (self.n_contact * 2**level + 1) * (n_y * 2**level + 1)


class _File(GeometryTable):
    BOUNDARIES: ClassVar[None] = None  # the file's physical curve groups, known once read
    FILE_KEY: ClassVar[str]  # the scene key naming the file
    FILE_ATTR: ClassVar[str]  # the field holding it
    body: Text | None = Field(
        None,
        description="a physical group of the file's cells: a surface group in a 2D file, a "
        "volume group in a 3D one (omitted: every such cell of the file)",
    )
    _dir: Path | None = None

    @model_validator(mode="before")
    @classmethod
    def _one_file(cls, data: Any) -> Any:
        if isinstance(data, dict) and "mesh" in data and "geo" in data:
            raise refuse(
                ["geo"],
                data["geo"],
                "either mesh (a mesh file) or geo (a gmsh geometry, needs gmsh), not both",
            )
        return data

    @model_validator(mode="after")
    def _scene_dir(self, info: ValidationInfo) -> _File:
        scene_file = (info.context or {}).get("file")
        if scene_file and not scene_file.startswith("<"):
            self._dir = Path(scene_file).parent
        return self

    def resolved(self) -> Path:
        """The file, resolved against the scene file's folder."""
        return resolve(self._dir, getattr(self, self.FILE_ATTR))

    @property
    def SIZE_KEY(self) -> str:  # noqa: N802 (the name every geometry has)
        """The file's key."""
        return self.FILE_KEY

    def size_value(self) -> str:
        """The resolved file."""
        return str(self.resolved())


class MeshFile(_File):
    """`{ mesh = "FILE", body = "GROUP" }`: a mesh file (gmsh .msh or any meshio format), 2D
    (its highest cells are surface cells in the plane z = 0) or 3D (linear tetrahedra or
    hexahedra), the group's cells refined `level` times (new boundary nodes on the file's
    polyline in 2D; each cell into 8, new nodes on the file's faces, in 3D); its physical
    groups of one dimension lower are the boundary parts."""

    FILE_KEY: ClassVar[str] = "mesh"
    FILE_ATTR: ClassVar[str] = "mesh_file"  # `mesh` is the method
    mesh_file: Text = Field(alias="mesh", description="the file, relative to the scene file")

    @property
    def DIM(self) -> int | None:  # noqa: N802 (the name every geometry has)
        """The file's highest cell dimension (None if it cannot be read: meshing names why)."""
        return file_dimension(self.resolved())

    def nodes(self, level: int) -> int:
        """The file's mesh's nodes after `level` uniform refinements."""
        key, planar = self.key("mesh"), self.DIM != 3
        return file_mesh(self.resolved(), self.body, key, planar).refined_nodes(level)

    def mesh(self, level: int) -> Mesh:
        """The body's mesh at refinement `level`."""
        self.check_size(level)
        key, planar = self.key("mesh"), self.DIM != 3
        return imported_mesh(self.resolved(), self.body, level, key, planar)


class GeoFile(_File):
    """`{ geo = "FILE.geo", body = "GROUP" }`: a gmsh geometry (needs the optional gmsh
    package), meshed and refined by gmsh with new boundary nodes on the geometry's curves."""

    FILE_KEY: ClassVar[str] = "geo"
    FILE_ATTR: ClassVar[str] = "geo"
    DIM: ClassVar[int] = 2
    geo: Text = Field(description="the .geo file, relative to the scene file")
    body: Text | None = Field(
        None, description="a physical surface group (omitted: every surface cell of the file)"
    )

    def nodes(self, level: int) -> int:
        """gmsh's level-0 mesh's nodes after `level` uniform refinements (gmsh refines by
        splitting every cell as `fem.refine.refine` does)."""
        return geo_mesh(self.resolved(), self.body, 0, self.key("geo")).refined_nodes(level)

    def mesh(self, level: int) -> Mesh:
        """The body's mesh at refinement `level`."""
        self.check_size(level)
        return geo_mesh(self.resolved(), self.body, level, self.key("geo"))


class Box(GeometryTable):
    """A box of hexahedra or tetrahedra, optionally with a curved bottom or top (`bottom_lift`,
    `top_lift`)."""

    BOUNDARIES: ClassVar[tuple[str, ...]] = ("left", "right", "front", "back", "bottom", "top")
    SIZE_KEY: ClassVar[str] = "cells"
    DIM: ClassVar[int] = 3
    kind: Literal["box"]
    x: Interval
    y: Interval
    z: Interval
    cells: BoxCells
    element: Literal["hexahedron", "tetra"] = "hexahedron"
    bottom_lift: Expression | None = None
    top_lift: Expression | None = None

    def nodes(self, level: int) -> int:
        """The grid's nodes (tetrahedra split the hexahedra without new nodes)."""
        return int(np.prod([c * 2**level + 1 for c in self.cells]))

    def mesh(self, level: int) -> Mesh:
        """The mesh at refinement `level`."""
        self.check_size(level)
        z0, z1 = self.z
        with _meshing(self):
            mesh = box(
                tuple(self.x), tuple(self.y), tuple(self.z), tuple(self.cells), self.element, level
            )
            if self.bottom_lift is not None:
                mesh = transform(mesh, _lifted(self.bottom_lift, z0, lambda z: z1 - z, z1 - z0))
            if self.top_lift is not None:
                mesh = transform(mesh, _lifted(self.top_lift, z1, lambda z: z - z0, z1 - z0))
        return mesh


def _lifted(
    h: Expression, at: float, weight: Callable[[np.ndarray], np.ndarray], height: float
) -> Callable[[np.ndarray], np.ndarray]:
    """The node map z += h(x, y, at)·weight(z)/height (a box's curved bottom or top)."""

    def lift(p: np.ndarray) -> np.ndarray:
        dz = h(p[:, 0], p[:, 1], np.full(len(p), at))  # (n,)
        p[:, 2] += dz * weight(p[:, 2]) / height
        return p

    return lift


class Extruded(GeometryTable):
    """A built-in 2D geometry extruded along z in layers of hexahedra (plane-strain scenes)."""

    SIZE_KEY: ClassVar[str] = "layers"
    DIM: ClassVar[int] = 3
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

    def mesh(self, level: int) -> Mesh:
        """The section's mesh at `level` extruded in layers·2^level layers."""
        self.check_size(level)
        m2 = self.section.mesh(level)
        layers = self.layers * 2**level
        if m2.cells.shape[1] != 4:
            raise SceneError(
                self.key("section"), self.section.model_dump(), "a section of quadrilaterals"
            )
        return extrude(m2, tuple(self.z), layers)


def _tag(v: Any) -> str | None:
    """The union member of a geometry table: its `kind`, or "mesh"/"geo" for a file."""
    if isinstance(v, dict):
        if "kind" in v:
            return v["kind"] if isinstance(v["kind"], str) else None
        return "mesh" if "mesh" in v else "geo" if "geo" in v else None
    if isinstance(v, _File):
        return v.FILE_KEY
    return getattr(v, "kind", None)


def _known_kind(kinds: tuple[str, ...], files: str) -> BeforeValidator:
    """An unknown `kind` is refused at `kind` (the union's own error would name the table)."""

    def check(v: Any) -> Any:
        if isinstance(v, dict) and "kind" in v and v["kind"] not in kinds:
            raise refuse(
                ["kind"], v["kind"], "one of " + ", ".join(kinds) + f" (or a file: {files})"
            )
        return v

    return BeforeValidator(check)


def _union(members: dict[str, type[Section]], files: str) -> Any:
    """The annotated union of geometry tables `members` (tag → Section), told apart by `kind`
    (a file by its `mesh` or `geo` key, `_tag`); `files` says which file tables it takes."""
    kinds = tuple(t for t in members if t not in ("mesh", "geo"))
    return Annotated[
        reduce(operator.or_, [Annotated[m, Tag(t)] for t, m in members.items()]),
        Discriminator(
            _tag,
            custom_error_type="geometry",
            custom_error_message="a table with kind = " + " | ".join(kinds) + f", or with {files} "
            "(and body = GROUP)",
        ),
        _known_kind(kinds, files),
    ]


# The geometry kinds: add a kind by adding a Section with a `kind` literal, DIM, BOUNDARIES
# (None: known only once meshed) and mesh(level) to the union.
GEOMETRIES = {
    "rectangle": Rectangle,
    "half_disc": HalfDisc,
    "cradle": Cradle,
    "box": Box,
    "extruded": Extruded,
    "mesh": MeshFile,
    "geo": GeoFile,
}
FILES = "mesh = FILE or geo = FILE.geo"
Geometry = _union(GEOMETRIES, FILES)
PLANE_KINDS = ("rectangle", "half_disc", "cradle", "mesh", "geo")  # a 2D-only plug-in's
PlaneGeometry = Annotated[
    _union({k: GEOMETRIES[k] for k in PLANE_KINDS}, FILES),
    AfterValidator(lambda g: _in_dimension(g, 2)),
]
UNION_TAGS.update(("geometry", k) for k in GEOMETRIES)
# the built-in kinds of each dimension: 2 (rectangle, half_disc, cradle), 3 (box, extruded)
KINDS = {
    d: tuple(k for k, g in GEOMETRIES.items() if not issubclass(g, _File) and g.DIM == d)
    for d in (2, 3)
}
CELLS = {2: "surface cells in the plane z = 0", 3: "a volume with tetrahedra or hexahedra"}


def wrong_dimension(g: GeometryTable, dim: int) -> tuple[list[str], Any, str] | None:
    """(key, value, what is allowed) if the geometry table `g` is not of dimension `dim` (a
    scene of that dimension); None if it is (or if it is an unreadable file)."""
    if g.DIM in (None, dim):
        return None
    if isinstance(g, _File):
        file = getattr(g, g.FILE_ATTR)
        return [g.FILE_KEY], file, f"a {dim}D mesh file ({CELLS[dim]}): the scene is {dim}D"
    kinds = " | ".join(KINDS[dim])
    return ["kind"], g.kind, f"kind = {kinds}, or a {dim}D mesh file: the scene is {dim}D"


def _in_dimension(g: GeometryTable, dim: int) -> GeometryTable:
    wrong = wrong_dimension(g, dim)
    if wrong is not None:
        raise refuse(*wrong)
    return g


def check_sizes(model: Section, level: int) -> None:
    """`check_size(level)` of every geometry in the validated scene `model` (any plug-in's:
    the tables are walked), so a level too large for one body is refused before anything is
    built or solved."""
    todo: list[Any] = [model]
    while todo:
        item = todo.pop()
        if isinstance(item, GeometryTable):
            item.check_size(level)
        elif isinstance(item, Section):
            todo.extend(getattr(item, name) for name in type(item).model_fields)
        elif isinstance(item, dict):
            todo.extend(item.values())
        elif isinstance(item, list | tuple):
            todo.extend(item)


@contextmanager
def _meshing(t: Section) -> Iterator[None]:
    """A ValueError while meshing (inverted or degenerate cells, zero-length boundary segments)
    becomes a SceneError naming the geometry table `t`."""
    with np.errstate(all="ignore"):
        try:
            yield
        except ValueError as err:
            raise SceneError(
                t._path, t.model_dump(), f"a geometry that meshes into valid cells ({err})"
            ) from None


def _meshed(t: Section, mesher, *args) -> Mesh:
    """Call a 2D mesher and trace every boundary part (refusals as for `_meshing`)."""
    with _meshing(t):
        mesh = mesher(*args)
        for part in mesh.boundaries:
            trace(mesh, part)
        return mesh
