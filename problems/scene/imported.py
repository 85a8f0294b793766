"""Meshes from files in scenes: `geometry = { mesh = "part.msh", body = "plate" }`, or
`geometry = { geo = "part.geo", body = "plate" }` (meshed by the optional gmsh package).

The path is relative to the scene file's folder; `body` names a physical surface group (omitted:
every surface cell of the file is the body); the file's physical curve groups on that body's
boundary become its boundary parts, usable wherever a scene names a boundary (Dirichlet data,
loads, potentials, contact). `--level L` refines the file's mesh uniformly L times; new boundary
nodes stay on the file's polyline, so against a curved exact boundary the error stalls at the
polyline's geometric error (docs/design.md, "Meshes from files"). From a `.geo` file gmsh meshes
and refines, putting new boundary nodes on the geometry's curves.

A 3D scene's geometry `{ mesh = "part.msh", body = "bracket" }` names a physical volume group;
its physical surface groups become the boundary parts (`imported_mesh`, `fem.mesh_import`),
and a level refines every cell into 8 (`fem.refine`, new nodes on the file's faces).

Everything here is independent of how the scene is read: `imported_mesh` takes the resolved
path, the group name and the key to blame, and turns `fem.mesh_import` refusals into
SceneErrors.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from fem.mesh import Mesh
from fem.mesh_import import MeshFile, MeshImportError, body_mesh, mesh_geo, read_mesh
from fem.mesh_import import cell_dimension as mesh_dim
from fem.mesh_import import require_curve as _require_curve
from fem.refine import refine
from problems.errors import SceneError


@lru_cache(maxsize=8)
def _read(path: str, mtime_ns: int, size: int, planar: bool = True) -> MeshFile:
    """Read once per file version: a two-body file is read once for both bodies."""
    del mtime_ns, size  # part of the cache key only
    return read_mesh(path, planar)


def resolve(scene_dir: Path | None, name: str) -> Path:
    """The mesh file `name` relative to the scene file's folder (absolute paths kept)."""
    p = Path(name).expanduser()
    return p if p.is_absolute() or scene_dir is None else scene_dir / p


@lru_cache(maxsize=8)
def _geo(path: str, mtime_ns: int, size: int, level: int) -> MeshFile:
    """Mesh a .geo file at a level once: both bodies of a two-body geometry use one meshing."""
    del mtime_ns, size  # part of the cache key only
    return mesh_geo(path, level)


def _stat(path: Path, key: str, what: str):
    try:
        return path.stat()
    except OSError as err:
        raise SceneError(
            key, str(path), f"an existing {what}, relative to the scene file ({err.strerror})"
        ) from None


def file_dimension(path: Path) -> int | None:
    """The highest cell dimension (2 or 3) of the mesh file `path`; None if it cannot be read
    (building its body then names why)."""
    try:
        st = path.stat()
        mf = _read(str(path), st.st_mtime_ns, st.st_size, False)
    except (OSError, MeshImportError):
        return None
    dims = [mesh_dim(cell_type) for cell_type, _, _ in mf.blocks]
    return max(dims) if dims and max(dims) in (2, 3) else None


def file_mesh(path: Path, body: str | None, key: str, planar: bool = True):
    """The body `body` of the mesh file `path`, unrefined: a 2D `Mesh` (planar) or a 3D
    one. SceneError naming `key` and the file for a missing or unusable file,
    an unknown group (the available ones listed), unsupported or invalid cells."""
    st = _stat(path, key, "mesh file")
    try:
        mf = _read(str(path), st.st_mtime_ns, st.st_size, planar)
        return body_mesh(mf, body)
    except MeshImportError as err:
        raise SceneError(key, str(path), f"{err.what}: {err.allowed}") from None


def imported_mesh(path: Path, body: str | None, level: int, key: str, planar: bool = True) -> Mesh:
    """The body `body` of the mesh file `path` (a physical surface group, or with `planar`
    False a volume group of a 3D file), refined `level` times (new boundary nodes on the file's
    polyline; in 3D each cell into 8, new nodes on the file's faces); SceneErrors naming `key`
    (the scene's mesh key) as for `file_mesh`."""
    return refine(file_mesh(path, body, key, planar), level)


def geo_mesh(path: Path, body: str | None, level: int, key: str) -> Mesh:
    """The body `body` of the gmsh geometry `path` (.geo), meshed and refined `level` times by
    gmsh (optional dependency): new boundary nodes lie on the geometry's curves, so rates on
    curved domains do not stall at a polyline's error. Refusals as for `imported_mesh`, and
    without gmsh a SceneError saying how to install it or what to give instead. The level-0
    mesh is made first: the file and the group are refused before a finer meshing."""
    st = _stat(path, key, "gmsh geometry file")
    name = str(path)
    try:
        base = body_mesh(_geo(name, st.st_mtime_ns, st.st_size, 0), body)
        return (
            base if level == 0 else body_mesh(_geo(name, st.st_mtime_ns, st.st_size, level), body)
        )
    except MeshImportError as err:
        raise SceneError(key, str(path), f"{err.what}: {err.allowed}") from None


def require_curve(mesh: Mesh, part: str, key: str, value: str) -> None:
    """SceneError naming `key` unless boundary part `part` is one simple curve (contact
    boundaries and curves to plot along must be; Dirichlet parts need not)."""
    try:
        _require_curve(mesh, part)
    except ValueError as err:
        raise SceneError(
            key, value, f"a boundary part that is one simple curve, without branches ({err})"
        ) from None
