"""3D meshes made elsewhere (gmsh .msh v2/v4 and the other formats meshio reads): a physical
volume group is a body, a physical surface group a boundary part.

`body_mesh3d` cuts one body out of a `fem.mesh_import.MeshFile` read with ``planar=False`` as a
`fem.mesh3d.Mesh3D` in this package's conventions (docs/fem3d.md, "3D meshes from files"):

- the body's nodes renumbered 0 … n−1 in the file's order;
- one cell type per body: linear tetrahedra ("tetra", P1) or trilinear hexahedra
  ("hexahedron", Q1; gmsh's node order is meshio's and ours); a cell with det J < 0 (the
  mirror image of our local order) is renumbered to det J > 0, then `fem.mesh3d.check_cells`
  refuses the cells still inverted or degenerate;
- each boundary part: the faces of a surface group (triangles on a tetrahedral body,
  quadrilaterals on a hexahedral one) that lie on the body's boundary, oriented outward. Faces
  of the group whose nodes are not all in the body belong to another body and are left out.

Refused with `MeshImportError` naming the file, the group or cell and what is allowed: an
unknown group (the available ones listed), cells other than linear tetrahedra/hexahedra in a
body, mixed cell types, two nodes of the body at the same point, inverted or degenerate
cells, a surface group with faces inside the body, a surface group whose face type does not
match the body's cells.
"""

from __future__ import annotations

import numpy as np

from .elements3d import FACES
from .mesh3d import Mesh3D, check_cells, exterior_faces, jacobian_determinants
from .mesh_import import MeshFile, MeshImportError, _dim, body_cells

VOLUME_CELLS = {"tetra": 4, "hexahedron": 8}  # meshio cell types accepted in a body
FACE_CELLS = {"tetra": "triangle", "hexahedron": "quad"}  # boundary faces of each body type
MIRROR = {  # a renumbering that turns a cell of det J < 0 into one of det J > 0
    "tetra": np.array([0, 2, 1, 3]),
    "hexahedron": np.array([4, 5, 6, 7, 0, 1, 2, 3]),
}


def body_mesh3d(mf: MeshFile, body: str | None = None) -> Mesh3D:
    """The body `body` (a physical volume group; None: every volume cell of the file) as a
    Mesh3D, with every physical surface group that lies on its boundary as a boundary part."""
    if mf.points.shape[1] != 3:
        raise ValueError("body_mesh3d needs a MeshFile read with planar=False")
    where, ctype, cells, points, new_id = body_cells(
        mf,
        body,
        3,
        VOLUME_CELLS,
        "linear tetrahedra ('tetra') or hexahedra ('hexahedron'); mesh with element order 1 "
        "(gmsh -order 1), without prisms or pyramids",
        "all tetrahedra or all hexahedra (gmsh: Mesh.RecombineAll = 1 and "
        "Mesh.Recombine3DAll = 1, or transfinite volumes)",
    )
    cells = _oriented(mf.path, where, points, cells, ctype)
    return Mesh3D(points, cells, _boundaries(mf, where, new_id, points, cells, ctype))


def _oriented(path: str, where: str, points: np.ndarray, cells: np.ndarray, ctype: str):
    """Cells renumbered to det J > 0 at the centroid; refusal of inverted/degenerate cells."""
    mesh = Mesh3D(points, cells)
    det = jacobian_determinants(mesh, np.zeros((1, 3)) + (0.25 if ctype == "tetra" else 0.0))
    cells = np.where(det[:, :1] < 0, cells[:, MIRROR[ctype]], cells)  # (n_cells, k)
    try:
        check_cells(Mesh3D(points, cells))
    except ValueError as err:
        raise MeshImportError(
            path, f"{where}: {err}", "cells of positive volume (not flat, not folded)"
        ) from None
    return cells


def _boundaries(
    mf: MeshFile,
    where: str,
    new_id: np.ndarray,
    points: np.ndarray,
    cells: np.ndarray,
    ctype: str,
) -> dict[str, np.ndarray]:
    """Surface groups on the body's boundary → outward faces (n_faces, 3|4)."""
    ext = exterior_faces(cells, ctype)  # (n_ext, k) outward
    k = ext.shape[1]
    all_faces = np.sort(cells[:, FACES[ctype]].reshape(-1, k), axis=1)  # (n_c n_f, k)
    ext_keys = np.sort(ext, axis=1)
    out: dict[str, np.ndarray] = {}
    for name in mf.names(2):
        tag = mf.groups[name][1]
        pieces = [(t, d[p == tag]) for t, d, p in mf.blocks if _dim(t) == 2]
        pieces = [(t, d) for t, d in pieces if len(d)]
        local = [(t, new_id[d]) for t, d in pieces]
        local = [(t, d[(d >= 0).all(axis=1)]) for t, d in local]  # faces within this body
        local = [(t, d) for t, d in local if len(d)]
        if not local:
            continue
        wrong = [t for t, _ in local if t != FACE_CELLS[ctype]]
        if wrong:
            raise MeshImportError(
                mf.path,
                f"surface group {name!r} on {where} has faces of type {wrong[0]!r}",
                f"{FACE_CELLS[ctype]!r} faces on a body of {ctype!r} cells (linear, order 1)",
            )
        keys = np.sort(np.concatenate([d for _, d in local]), axis=1)  # (n_g, k)
        on = _rows_in(keys, ext_keys)  # (n_g,) index into ext or −1
        inside = (on < 0) & (_rows_in(keys, all_faces) >= 0)
        if inside.any():
            i = int(np.flatnonzero(inside)[0])
            raise MeshImportError(
                mf.path,
                f"surface group {name!r} has {int(inside.sum())} face(s) inside {where}, e.g. "
                f"the face with corners {points[keys[i]].tolist()}",
                "boundary parts on the body's boundary (an interface between two bodies: mesh "
                "them as two physical volumes with their own surfaces)",
            )
        if (on >= 0).any():
            out[name] = ext[np.unique(on[on >= 0])]
    return out


def _rows_in(rows: np.ndarray, table: np.ndarray) -> np.ndarray:
    """For each row of `rows` (n, k) its index in `table` (m, k) (rows sorted alike), or −1."""
    both = np.concatenate([table, rows])
    _, inv = np.unique(both, axis=0, return_inverse=True)
    inv = inv.ravel()
    first = np.full(inv.max() + 1, -1)
    first[inv[: len(table)][::-1]] = np.arange(len(table))[::-1]
    return first[inv[len(table) :]]
