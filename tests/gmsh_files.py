"""Gmsh files written from built-in meshes, for the tests (mixvi reads .msh files; it never
writes them): `write_msh`."""

from __future__ import annotations

from collections import Counter
from os import PathLike
from pathlib import Path

import numpy as np

from fem.elements import FACET_TYPE
from fem.mesh import Mesh


def write_msh(
    path: str | PathLike,
    bodies: dict[str, Mesh],
    file_format: str = "gmsh22",
    binary: bool = False,
) -> None:
    """Write meshes as one gmsh file (meshio's `file_format`: "gmsh22" = v2.2, "gmsh" = v4.1):
    each body a physical surface (2D `Mesh`) or volume (3D) named for it, each boundary
    part a physical curve (2D) or surface (3D) named `part` (`body_part` where two bodies have
    a part of that name; 3D only as v2.2). Nodes of different bodies are not merged. The
    tests use it to hand built-in meshes to `body_mesh` (ASCII, or `binary`)."""
    import meshio

    dims = {m.points.shape[1] for m in bodies.values()}
    if len(dims) != 1:
        raise ValueError("write_msh: all bodies 2D or all 3D")
    dim = dims.pop()
    if dim == 3 and file_format != "gmsh22":  # meshio's v4.1 writer drops entities without a
        raise ValueError("write_msh: 3D meshes as gmsh22")  # node of their own (its reader fails)
    counts = Counter(p for m in bodies.values() for p in m.boundaries)  # bodies with a part
    points, cells, phys, field, dim_tags = [], [], [], {}, []  # phys: physical = geometrical
    offset, tag = 0, 1
    for bname, m in bodies.items():
        faces = FACET_TYPE[m.cell_type]
        field[bname] = np.array([tag, dim])
        dt = np.tile([dim, tag], (m.n_nodes, 1))  # (n, 2) the entity each node is classified on
        cells.append((m.cell_type, m.cells + offset))
        phys.append(np.full(m.n_cells, tag))
        tag += 1
        for p, e in m.boundaries.items():
            name = p if counts[p] == 1 else f"{bname}_{p}"
            field[name] = np.array([tag, dim - 1])
            cells.append((faces, e + offset))
            phys.append(np.full(len(e), tag))
            dt[e.ravel()] = [dim - 1, tag]
            tag += 1
        points.append(m.points)
        dim_tags.append(dt)
        offset += m.n_nodes
    out = meshio.Mesh(
        np.pad(np.concatenate(points), ((0, 0), (0, 3 - dim))),  # (n, 3)
        cells,
        point_data={"gmsh:dim_tags": np.concatenate(dim_tags)},
        cell_data={"gmsh:physical": phys, "gmsh:geometrical": phys},
        field_data=field,
    )
    out.write(str(Path(path)), file_format=file_format, binary=binary)
