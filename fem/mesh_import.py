"""Meshes made elsewhere: gmsh .msh (v2 and v4) and the other formats meshio reads, 2D and 3D.

A mesh file may hold several bodies. Named **physical groups** (gmsh) select them: a group of
the mesh's dimension d (surfaces in 2D, volumes in 3D) is a body, a group of dimension d − 1
(curves, surfaces) a boundary part. `read_mesh` reads the file once (``planar``: a 2D mesh in
the plane z = 0, or False: 3D); `body_mesh` cuts one body out as a `fem.mesh.Mesh` in this
package's conventions (docs/design.md, "Meshes"; docs/fem3d.md, "3D meshes from files"):

- the body's nodes renumbered 0 … n−1 in the file's order (2D: the z coordinate dropped, it
  must be 0);
- one cell type per body: all triangles or all quadrilaterals (gmsh's ``Mesh.RecombineAll``
  makes the second) in 2D, all linear tetrahedra or all trilinear hexahedra in 3D (gmsh's node
  order is meshio's and ours);
- 2D cells counterclockwise (a body whose cells are all clockwise, as gmsh writes a surface
  whose normal points along −z, is flipped as a whole); a 3D cell with det J < 0 (the mirror
  image of our local order) renumbered to det J > 0;
- each boundary part: the facets of the group (line cells; triangles on a tetrahedral body,
  quadrilaterals on a hexahedral one) that lie on the body's boundary, oriented outward; in 2D
  ordered along the part (several pieces allowed; whether a part is one simple curve is
  checked where that matters: `require_curve`). Facets whose nodes are not all in the body
  belong to another body and are left out.

Refused with `MeshImportError` (a ValueError naming the file, the group or cell and what is
allowed): unreadable files, unknown physical groups (the available ones are listed), other
cell types in a body, mixed cell types, two nodes of a body at the same point (a mesh not made
coherent), cells with mixed orientation (2D: a fold), inverted or degenerate cells, non-convex
quadrilaterals, a group with facets inside the body or of the wrong type, a z coordinate other
than 0 in 2D.
"""

from __future__ import annotations

import contextlib
import difflib
import io
import tempfile
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np

from . import mesh_bounds
from .elements import FACET_TYPE, FACETS, reference_element
from .jacobians import check_cells, jacobian_determinants
from .mapped import _order_edges
from .mesh import Mesh, exterior_facets, find_rows

SURFACE_CELLS = {"triangle": 3, "quad": 4}  # meshio cell types accepted in a 2D body
VOLUME_CELLS = {"tetra": 4, "hexahedron": 8}  # meshio cell types accepted in a 3D body
# body dimension -> (accepted cell types, what is allowed, how to get one cell type)
BODY_CELLS = {
    2: (
        SURFACE_CELLS,
        "linear triangles ('triangle') or quadrilaterals ('quad'); mesh with element order 1 "
        "(gmsh -order 1) and without 3D cells",
        "all triangles or all quadrilaterals (gmsh: Mesh.RecombineAll = 1 for quadrilaterals "
        "everywhere)",
    ),
    3: (
        VOLUME_CELLS,
        "linear tetrahedra ('tetra') or hexahedra ('hexahedron'); mesh with element order 1 "
        "(gmsh -order 1), without prisms or pyramids",
        "all tetrahedra or all hexahedra (gmsh: Mesh.RecombineAll = 1 and "
        "Mesh.Recombine3DAll = 1, or transfinite volumes)",
    ),
}
FACET_NAMES = {2: "edge", 3: "face"}  # what a boundary facet of a body is, for messages
MIRROR = {  # a renumbering that turns a 3D cell of det J < 0 into one of det J > 0
    "tetra": np.array([0, 2, 1, 3]),
    "hexahedron": np.array([4, 5, 6, 7, 0, 1, 2, 3]),
}
IGNORED_CELLS = ("vertex",)  # point groups: no role in a body
# A cell whose signed area is at most AREA_TOL × (longest edge)² counts as degenerate.
AREA_TOL = 1e-12
# |z| of a node must be at most Z_TOL × the mesh's extent (the file holds a planar mesh).
Z_TOL = 1e-12
# Two nodes of a body closer than NODE_TOL × the body's extent are the same point (refused).
NODE_TOL = 1e-10
# |coordinate| of a node at most this: cubes (volumes, Jacobians in 3D) stay finite
MAX_COORD = 1e100


class MeshImportError(ValueError):
    """A mesh file that cannot be used: which file, which group or cell, what is allowed."""

    def __init__(self, file: str, what: str, allowed: str):
        self.file, self.what, self.allowed = file, what, allowed
        super().__init__(f"{file}: {what}: {allowed}")


@dataclass(frozen=True)
class MeshFile:
    """A mesh file as read: points and cell blocks with their physical groups.

    points : (n, 2) coordinates.
    blocks : list of (cell type, (n_cells, k) node ids, (n_cells,) physical tag or −1).
    groups : physical group name → (dimension, tag).
    """

    path: str
    points: np.ndarray
    blocks: list[tuple[str, np.ndarray, np.ndarray]]
    groups: dict[str, tuple[int, int]]

    def names(self, dim: int) -> list[str]:
        """Sorted names of the physical groups of dimension `dim`."""
        return sorted(n for n, (d, _) in self.groups.items() if d == dim)

    def _group(self, name: str, dim: int, what: str) -> int:
        """The tag of the named group of dimension `dim`; refusal listing the available ones."""
        have = self.names(dim)
        if self.groups.get(name, (None, None))[0] == dim:
            return self.groups[name][1]
        hint = difflib.get_close_matches(name, have, n=1)
        extra = f" (did you mean {hint[0]!r}?)" if hint else ""
        listed = ", ".join(repr(n) for n in have) if have else "none"
        raise MeshImportError(
            self.path,
            f"{what} {name!r}",
            f"the name of a physical group of dimension {dim} in this file{extra}; "
            f"available: {listed}",
        )


def read_mesh(path: str | PathLike, planar: bool = True) -> MeshFile:
    """Read a mesh file with meshio (format from the file name; gmsh .msh v2 or v4, ...).

    planar: a 2D mesh in the plane z = 0 (points (n, 2), refused otherwise); False keeps the
    three coordinates (points (n, 3): a 3D mesh)."""
    import meshio

    path = str(path)

    def error(what: str, allowed: str) -> MeshImportError:
        return MeshImportError(path, what, allowed)

    size = mesh_bounds.check_file(path, error)  # a regular file, not too large
    mesh_bounds.scan_gmsh_ascii(path, size, error)  # counts and tags, before any allocation
    try:  # meshio prints its own complaint and may even call sys.exit: keep it quiet
        with (
            contextlib.redirect_stdout(io.StringIO()),
            contextlib.redirect_stderr(io.StringIO()),
            mesh_bounds.address_space_cap(size) as budget,
        ):
            m = meshio.read(path)
    except MemoryError:
        raise MeshImportError(
            path,
            f"reading it needs more than {budget / 2**20:,.0f} MiB",
            "a mesh file whose counts and tags fit its size (one far larger than the file "
            "makes meshio allocate for it)",
        ) from None
    except (Exception, SystemExit) as err:  # ReadError, KeyError, ValueError, exit(1), ...
        first = str(err).splitlines()[0][:200] if str(err) else type(err).__name__
        raise MeshImportError(
            path, "unreadable", f"a mesh file meshio can read, e.g. gmsh .msh v2/v4 ({first})"
        ) from None
    pts = np.asarray(m.points, dtype=float)
    if pts.ndim != 2 or pts.shape[0] == 0:
        raise MeshImportError(path, "no nodes", "a mesh with nodes")
    if not planar:
        pts = np.pad(pts, ((0, 0), (0, 3 - pts.shape[1]))) if pts.shape[1] < 3 else pts
    elif pts.shape[1] == 3:
        extent = float(np.ptp(pts[:, :2], axis=0).max()) if len(pts) > 1 else 1.0
        z = np.abs(pts[:, 2])
        if z.max() > Z_TOL * max(extent, 1e-300):
            i = int(np.argmax(z))
            raise MeshImportError(
                path, f"node {i} at {pts[i].tolist()}", "a planar mesh in the plane z = 0"
            )
    if not np.isfinite(pts).all():
        i = int(np.flatnonzero(~np.isfinite(pts).all(axis=1))[0])
        raise MeshImportError(path, f"node {i} at {pts[i].tolist()}", "finite coordinates")
    big = np.abs(pts).max()
    if big > MAX_COORD:
        i = int(np.argmax(np.abs(pts).max(axis=1)))
        raise MeshImportError(
            path,
            f"node {i} at {pts[i].tolist()}",
            f"coordinates of magnitude at most {MAX_COORD:g} (areas and volumes stay finite)",
        )
    tags = m.cell_data.get("gmsh:physical")
    blocks = []
    for i, block in enumerate(m.cells):
        phys = np.asarray(tags[i], dtype=int) if tags is not None else np.full(len(block.data), -1)
        data = np.asarray(block.data, dtype=np.int64)  # (n_cells, k) node ids
        outside = data[(data < 0) | (data >= len(pts))]  # (n_out,) node ids no node has
        if outside.size:
            raise MeshImportError(
                path,
                f"a {block.type!r} cell names node {int(outside[0])} (0-based)",
                f"node ids from 0 to {len(pts) - 1} (the file's nodes)",
            )
        if len(phys) != len(data):
            raise MeshImportError(
                path, f"{len(phys)} physical tags for {len(data)} {block.type!r} cells", "one each"
            )
        blocks.append((block.type, data, phys))
    groups = {str(k): (int(v[1]), int(v[0])) for k, v in (m.field_data or {}).items()}
    return MeshFile(path, (pts[:, :2] if planar else pts).copy(), blocks, groups)


def mesh_geo(path: str | PathLike, level: int = 0) -> MeshFile:
    """Mesh a gmsh geometry file (.geo) with the optional gmsh package and refine it `level`
    times with gmsh: new boundary nodes are put on the geometry's curves (not on the level-0
    polyline), interior ones at edge midpoints. The mesh options are the .geo file's own."""
    path = str(path)
    mesh_bounds.check_file(path, lambda what, allowed: MeshImportError(path, what, allowed))
    try:
        import gmsh
    except ImportError:
        raise MeshImportError(
            path,
            "a .geo geometry",
            "the optional gmsh package (pip install gmsh) to mesh it; or a mesh file made from "
            "it (gmsh -2 FILE.geo), whose refinement keeps new boundary nodes on its polyline",
        ) from None
    except OSError as err:  # installed, but its library misses the system's OpenGL/X11 ones
        raise MeshImportError(
            path,
            "a .geo geometry",
            f"a gmsh package that loads ({err}; on Debian/Ubuntu: apt-get install libgl1 "
            "libglu1-mesa libxrender1 libxcursor1 libxft2 libxinerama1); or a mesh file made "
            "from it (gmsh -2 FILE.geo)",
        ) from None
    own = not gmsh.isInitialized()
    if own:
        gmsh.initialize(["-noenv"], readConfigFiles=False, interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        with tempfile.TemporaryDirectory(prefix="mixvi-geo-") as tmp:
            try:
                gmsh.open(path)
                gmsh.model.mesh.generate(2)
                for _ in range(level):
                    gmsh.model.mesh.refine()
                gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
                out = str(Path(tmp) / "mesh.msh")
                gmsh.write(out)
            except Exception as err:  # gmsh raises plain Exceptions with its log line
                first = str(err).splitlines()[0][:200] if str(err) else type(err).__name__
                raise MeshImportError(
                    path, "gmsh failed", f"a .geo file gmsh meshes ({first})"
                ) from None
            mf = read_mesh(out)
    finally:
        gmsh.clear()
        if own:
            gmsh.finalize()
    return MeshFile(path, mf.points, mf.blocks, mf.groups)


def cell_dimension(cell_type: str) -> int:
    """The dimension of a meshio cell type (0 for the ignored ones: vertices)."""
    if cell_type in SURFACE_CELLS or cell_type.startswith(("triangle", "quad", "polygon")):
        return 2
    if cell_type.startswith("line"):
        return 1
    if cell_type in IGNORED_CELLS:
        return 0
    return 3


SHAPES = {2: "surface", 3: "volume"}  # what a body of each dimension is, for messages
CELL_NAMES = {
    "triangle": "triangles",
    "quad": "quadrilaterals",
    "tetra": "tetrahedra",
    "hexahedron": "hexahedra",
}


def body_mesh(mf: MeshFile, body: str | None = None) -> Mesh:
    """The body `body` as a Mesh of the file's dimension d (`read_mesh`'s `planar`): the
    physical group `body` of dimension d, surfaces (2D) or volumes (3D) (None: every cell of
    dimension d, and — to refuse them — every cell of a higher one), its nodes renumbered
    0 … n−1 in the file's order. Every physical group of dimension d − 1 that lies on its
    boundary is a boundary part. Refused naming the file and the body: a cell type other than
    `BODY_CELLS` allows, no cell, mixed types, two nodes at the same point (`distinct_nodes`);
    and as `_counterclockwise`, `_positive` and `_boundaries` say."""
    d = mf.points.shape[1]
    allowed, allowed_text, one_type_text = BODY_CELLS[d]
    where = "the file" if body is None else f"body {body!r}"
    tag = None if body is None else mf._group(body, d, "body")
    cells_of: dict[str, list[np.ndarray]] = {}
    for ctype, data, phys in mf.blocks:
        if cell_dimension(ctype) < d or (cell_dimension(ctype) > d and tag is not None):
            continue
        sel = data if tag is None else data[phys == tag]
        if len(sel) == 0:
            continue
        if ctype not in allowed:
            raise MeshImportError(
                mf.path, f"{len(sel)} cell(s) of type {ctype!r} in {where}", allowed_text
            )
        cells_of.setdefault(ctype, []).append(sel)
    if not cells_of:
        kinds = " or ".join(CELL_NAMES[c] for c in allowed)
        raise MeshImportError(mf.path, where, f"a {SHAPES[d]} with {kinds}")
    if len(cells_of) > 1:
        counts = ", ".join(f"{sum(map(len, v))} {k}" for k, v in cells_of.items())
        raise MeshImportError(
            mf.path,
            f"{where} mixes cell types ({counts})",
            f"one cell type per body: {one_type_text}",
        )
    cells_file = np.concatenate(next(iter(cells_of.values())))  # (n_cells, k) file node ids
    order = np.unique(cells_file.ravel())  # file node ids used by the body, in file order
    new_id = np.full(mf.points.shape[0], -1, dtype=np.int64)  # (n_file,)
    new_id[order] = np.arange(order.size)
    points = mf.points[order]  # (n, d)
    distinct_nodes(mf.path, where, points, order)
    cells = (_counterclockwise if d == 2 else _positive)(mf.path, where, points, new_id[cells_file])
    return Mesh(points, cells, _boundaries(mf, where, new_id, points, cells))


def distinct_nodes(path: str, where: str, points: np.ndarray, file_ids: np.ndarray) -> None:
    """Refuse two nodes of a body at the same point (a mesh not made coherent: the body would
    be cut along them). points (n, d) of the body; file_ids (n,) their 0-based ids in the file."""
    from scipy.spatial import cKDTree

    extent = float(np.ptp(points, axis=0).max()) if len(points) > 1 else 0.0
    pairs = cKDTree(points).query_pairs(NODE_TOL * extent, output_type="ndarray")  # (n_p, 2)
    if len(pairs):
        i, j = sorted(file_ids[pairs[0]].tolist())
        raise MeshImportError(
            path,
            f"{where}: {len(pairs)} pair(s) of nodes at the same point, e.g. file nodes {i} and "
            f"{j} at the same point {points[pairs[0, 0]].tolist()} (0-based, in file order)",
            "one node per point in a body (gmsh: Coherence Mesh, or BooleanFragments of the "
            "volumes before meshing)",
        )


def _counterclockwise(path: str, where: str, points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Cells made counterclockwise (all flipped if all are clockwise); refusal of folds,
    degenerate cells and non-convex quadrilaterals."""
    P = points[cells]  # (n_cells, k, 2)
    e_next = np.roll(P, -1, axis=1) - P  # (n_cells, k, 2) edge leaving corner i
    e_prev = np.roll(P, 1, axis=1) - P  # (n_cells, k, 2) edge arriving at corner i, reversed
    cross = e_next[..., 0] * e_prev[..., 1] - e_next[..., 1] * e_prev[..., 0]  # (n_cells, k)
    longest = (np.linalg.norm(e_next, axis=-1) ** 2).max(axis=1)  # (n_cells,)
    area = 0.5 * np.sum(
        P[..., 0] * np.roll(P[..., 1], -1, 1) - np.roll(P[..., 0], -1, 1) * P[..., 1], axis=1
    )
    tiny = AREA_TOL * longest
    neg, pos = area < -tiny, area > tiny
    if neg.all():
        cells, cross, neg, pos = cells[:, ::-1], -cross, pos, neg
    bad = np.flatnonzero(~pos)
    if bad.size:
        kind = "degenerate (zero area)" if np.abs(area[bad[0]]) <= tiny[bad[0]] else "inverted"
        raise MeshImportError(
            path,
            f"{where}: {bad.size} cell(s) inverted or degenerate, e.g. cell {bad[0]} ({kind}) "
            f"with corners {P[bad[0]].tolist()}",
            "cells of positive area, all with the same orientation",
        )
    if cells.shape[1] == 4:
        nonconvex = np.flatnonzero((cross <= AREA_TOL * longest[:, None]).any(axis=1))
        if nonconvex.size:
            i = nonconvex[0]
            raise MeshImportError(
                path,
                f"{where}: {nonconvex.size} quadrilateral(s) not strictly convex, e.g. cell {i} "
                f"with corners {P[i].tolist()}",
                "convex quadrilaterals (angles below 180°)",
            )
    return cells


def _positive(path: str, where: str, points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """3D cells renumbered to det J > 0 at the centroid (a cell with det J < 0 is the mirror
    image of our local order); refusal of the cells still inverted or degenerate."""
    mesh = Mesh(points, cells)
    centroid = reference_element(mesh.cell_type).centroid[None, :]  # (1, 3)
    det = jacobian_determinants(mesh, centroid)  # (n_cells, 1)
    cells = np.where(det < 0, cells[:, MIRROR[mesh.cell_type]], cells)  # (n_cells, k)
    try:
        check_cells(Mesh(points, cells))
    except ValueError as err:
        raise MeshImportError(
            path, f"{where}: {err}", "cells of positive volume (not flat, not folded)"
        ) from None
    return cells


def _boundaries(
    mf: MeshFile, where: str, new_id: np.ndarray, points: np.ndarray, cells: np.ndarray
) -> dict[str, np.ndarray]:
    """The physical groups of dimension d − 1 on the body's boundary → its outward facets
    (n_facets, k_facet); in 2D the edges ordered along each part (body on their left)."""
    ctype = Mesh(points, cells).cell_type
    d, ftype = points.shape[1], FACET_TYPE[ctype]
    ext = exterior_facets(cells, ctype)  # (n_ext, k) outward
    k = ext.shape[1]
    all_facets = np.sort(cells[:, FACETS[ctype]].reshape(-1, k), axis=1)  # (n_c n_f, k)
    ext_keys = np.sort(ext, axis=1)
    group = {1: "curve group", 2: "surface group"}[d - 1]
    out: dict[str, np.ndarray] = {}
    for name in mf.names(d - 1):
        tag = mf.groups[name][1]
        local = [(t, new_id[x[p == tag]]) for t, x, p in mf.blocks if cell_dimension(t) == d - 1]
        local = [(t, x[(x >= 0).all(axis=1)]) for t, x in local]  # facets within this body
        local = [(t, x) for t, x in local if len(x)]
        if not local:
            continue
        wrong = [t for t, _ in local if t != ftype]
        if wrong:
            raise MeshImportError(
                mf.path,
                f"{group} {name!r} on {where} has {FACET_NAMES[d]}s of type {wrong[0]!r}",
                f"{ftype!r} {FACET_NAMES[d]}s on a body of {ctype!r} cells (linear, element "
                "order 1)",
            )
        keys = np.sort(np.concatenate([x for _, x in local]), axis=1)  # (n_g, k)
        on = find_rows(ext_keys, keys)  # (n_g,) index into ext or −1
        inside = (on < 0) & (find_rows(all_facets, keys) >= 0)
        if inside.any():
            i = int(np.flatnonzero(inside)[0])
            raise MeshImportError(
                mf.path,
                f"{group} {name!r} has {int(inside.sum())} {FACET_NAMES[d]}(s) inside "
                f"{where}, e.g. the one with corners {points[keys[i]].tolist()}",
                "boundary parts on the body's boundary (an interface between two bodies: mesh "
                f"them as two physical {SHAPES[d]}s with their own {FACET_NAMES[d]}s)",
            )
        part = ext[np.unique(on[on >= 0])]  # (n_part, k) in the order of `ext`
        if d == 2 and len(part):  # edges along the part, from the lowest-numbered chain
            part = _order_edges(part[np.lexsort(np.sort(part, axis=1).T[::-1])])
        if len(part):
            out[name] = part
    return out


def require_curve(mesh: Mesh, part: str) -> None:
    """ValueError unless boundary part `part` is one simple curve (an open chain of edges,
    or one closed loop): contact boundaries must be."""
    from .facets import trace

    trace(mesh, part)
