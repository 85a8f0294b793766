"""Transitional re-export for branches in flight, issue 30; removed when the issue closes.

The 3D dual mortar moved to `fem.mortar` (one mortar for 2D and 3D), its polygon clipping to
`fem.clipping`, its multiplier bases to `fem.facets`."""

from .clipping import cells, clip, inverse_map, nearest_hits
from .facets import ENDS, dual_mass, multiplier_basis, rim_nodes
from .mortar import FACE_ORDER, QUAD_ORDER, couple, covered_nodes, nodal_rows
from .mortar import Mortar as Mortar3D
from .mortar import mortar_coupling as mortar_coupling3d

__all__ = [
    "ENDS",
    "FACE_ORDER",
    "QUAD_ORDER",
    "Mortar3D",
    "cells",
    "clip",
    "couple",
    "covered_nodes",
    "dual_mass",
    "inverse_map",
    "mortar_coupling3d",
    "multiplier_basis",
    "nearest_hits",
    "nodal_rows",
    "rim_nodes",
]
