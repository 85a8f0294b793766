"""Meshes from files in scenes: `geometry = { mesh = "part.msh", body = "plate" }`.

The path is relative to the scene file's folder; `body` names a physical surface group (omitted:
every surface cell of the file is the body); the file's physical curve groups on that body's
boundary become its boundary parts, usable wherever a scene names a boundary (Dirichlet data,
loads, potentials, contact). `--level L` refines the file's mesh uniformly L times; new boundary
nodes stay on the file's polyline, so against a curved exact boundary the error stalls at the
polyline's geometric error (docs/design.md, "Meshes from files").

Everything here is independent of how the scene is read: `imported_mesh` takes the resolved
path, the group name and the key to blame, and turns `fem.mesh_import` refusals into
SceneErrors.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from fem.mesh import Mesh
from fem.mesh_import import MeshFile, MeshImportError, body_mesh, read_mesh
from fem.mesh_import import require_curve as _require_curve
from fem.meshing import refine
from problems.errors import SceneError


@lru_cache(maxsize=8)
def _read(path: str, mtime_ns: int, size: int) -> MeshFile:
    """Read once per file version: a two-body file is read once for both bodies."""
    del mtime_ns, size  # part of the cache key only
    return read_mesh(path)


def resolve(scene_dir: Path | None, name: str) -> Path:
    """The mesh file `name` relative to the scene file's folder (absolute paths kept)."""
    p = Path(name).expanduser()
    return p if p.is_absolute() or scene_dir is None else scene_dir / p


def imported_mesh(
    path: Path, body: str | None, level: int, key: str, max_cells: int | None = None
) -> Mesh:
    """The body `body` of the mesh file `path`, refined `level` times.

    SceneError naming `key` (the scene's mesh key) and the file for a missing or unusable file,
    an unknown group (the available ones listed), unsupported or invalid cells, and a mesh that
    would exceed `max_cells` cells at this level.
    """
    try:
        st = path.stat()
    except OSError as err:
        raise SceneError(
            key, str(path), f"an existing mesh file, relative to the scene file ({err.strerror})"
        ) from None
    try:
        mesh = body_mesh(_read(str(path), st.st_mtime_ns, st.st_size), body)
    except MeshImportError as err:
        raise SceneError(key, str(path), f"{err.what}: {err.allowed}") from None
    cells = mesh.n_cells * 4**level
    if max_cells is not None and cells > max_cells:
        raise SceneError(
            key,
            str(path),
            f"a mesh of at most {max_cells:,} cells per body at the requested level "
            f"({mesh.n_cells} cells refined {level} times would have {cells:,})",
        )
    return refine(mesh, level)


def require_curve(mesh: Mesh, part: str, key: str, value: str) -> None:
    """SceneError naming `key` unless boundary part `part` is one simple curve (contact
    boundaries and curves to plot along must be; Dirichlet parts need not)."""
    try:
        _require_curve(mesh, part)
    except ValueError as err:
        raise SceneError(
            key, value, f"a boundary part that is one simple curve, without branches ({err})"
        ) from None
