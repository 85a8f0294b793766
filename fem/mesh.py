"""Unstructured 2D meshes of triangles (P1) or quadrilaterals (Q1) with named boundary parts."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class CellMesh:
    """What every mesh offers (2D `Mesh`, 3D `fem.mesh3d.Mesh3D`): `points` (n_nodes, d),
    `cells` (n_cells, k) and `boundaries` name -> (n_facets, k_facet) node lists."""

    points: np.ndarray
    cells: np.ndarray
    boundaries: dict[str, np.ndarray]

    @property
    def n_nodes(self) -> int:
        return self.points.shape[0]

    @property
    def n_cells(self) -> int:
        return self.cells.shape[0]

    def boundary_nodes(self, name: str) -> np.ndarray:
        """Sorted unique node indices of the boundary part `name`."""
        if name not in self.boundaries:
            raise KeyError(
                f"unknown boundary {name!r}; this mesh has: {', '.join(sorted(self.boundaries))}"
            )
        return np.unique(self.boundaries[name])

    @property
    def h(self) -> float:
        """Mesh size: the largest cell diameter."""
        P = self.points[self.cells]  # (n_cells, k, d)
        d = np.linalg.norm(P[:, :, None, :] - P[:, None, :, :], axis=-1)  # (n_cells, k, k)
        return float(d.max())


@dataclass(frozen=True, eq=False)
class Mesh(CellMesh):
    """A 2D mesh.

    points : (n_nodes, 2) float coordinates.
    cells : (n_cells, 3) triangles or (n_cells, 4) quadrilaterals, counterclockwise.
    boundaries : name -> (n_edges, 2) node pairs; each edge (a, b) has the domain on its left
        (boundary traversed counterclockwise); edges of one part are ordered along the part.
    """

    points: np.ndarray
    cells: np.ndarray
    boundaries: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def cell_type(self) -> str:
        """'triangle' or 'quad'."""
        return "triangle" if self.cells.shape[1] == 3 else "quad"

    def refined_nodes(self, times: int) -> int:
        """Nodes after `times` uniform refinements (`fem.meshing.refine`: every cell into 4 at
        its edge midpoints, quads also at their centre), counted without refining: with V
        nodes, E edges and C cells, one refinement gives V + E (+ C for quads) nodes,
        2E + 3C (triangles) or 2E + 4C (quads) edges and 4C cells."""
        k = self.cells.shape[1]
        pairs = np.stack([self.cells, np.roll(self.cells, -1, axis=1)], axis=2)  # (C, k, 2)
        V, C = self.n_nodes, self.n_cells
        E = len(np.unique(np.sort(pairs.reshape(-1, 2), axis=1), axis=0))
        for _ in range(times):
            V, E, C = V + E + (C if k == 4 else 0), 2 * E + k * C, 4 * C
        return V
