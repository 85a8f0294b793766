"""VTU output (ParaView) through meshio."""

from __future__ import annotations

from os import PathLike

import meshio
import numpy as np

from .mesh import Mesh


def _as_field(name: str, a: np.ndarray, n: int) -> np.ndarray:
    """(n,) scalars or (n, c) components; a flat interleaved 2-vector field (2n,) becomes
    (n, 2); 2-component fields are padded with zeros to 3 so ParaView shows them as vectors."""
    a = np.asarray(a)
    if a.ndim == 1 and a.size == 2 * n:
        a = a.reshape(n, 2)
    if a.shape[0] != n:
        raise ValueError(f"field {name!r} has {a.shape[0]} rows, expected {n}")
    return np.pad(a, ((0, 0), (0, 1))) if a.ndim == 2 and a.shape[1] == 2 else a


def write_vtu(
    path: str | PathLike,
    mesh: Mesh,
    point_data: dict[str, np.ndarray] | None = None,
    cell_data: dict[str, np.ndarray] | None = None,
) -> None:
    """Write a 2D or 3D `mesh` with nodal and per-cell fields to a .vtu file.

    Fields are (n,) scalars, (n, c) arrays, or flat interleaved 2-vector fields of length 2 n
    (e.g. a displacement dof vector); 2-component vectors get a zero third component.
    """
    out = meshio.Mesh(
        np.pad(mesh.points, ((0, 0), (0, 3 - mesh.dim))),  # (N, 3): 2D points get a zero z
        [(mesh.cell_type, mesh.cells)],
        point_data={k: _as_field(k, v, mesh.n_nodes) for k, v in (point_data or {}).items()},
        cell_data={k: [_as_field(k, v, mesh.n_cells)] for k, v in (cell_data or {}).items()},
    )
    out.write(str(path), file_format="vtu")
