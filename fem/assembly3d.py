"""Transitional re-export for branches in flight, issue 30; removed when the issue closes.

The 3D assembly is `fem.assembly` (one path for 2D and 3D).
"""

from .assembly import (
    CHUNK,
    Func,
    Geometry,
    boundary_load,
    cell_fields,
    cell_geometry,
    coupling_matrix,
    elasticity_matrix,
    h1_seminorm_error,
    interpolate,
    l2_error,
    mass_matrix,
    permittivity_matrix,
    piezo_matrix,
    strain_operator,
    vector_dofs,
    volume_load,
)
from .assembly import Func as Func3
from .assembly import Geometry as Geometry3D
from .assembly import facet_geometry as face_geometry

__all__ = [
    "CHUNK",
    "Func",
    "Func3",
    "Geometry",
    "Geometry3D",
    "boundary_load",
    "cell_fields",
    "cell_geometry",
    "coupling_matrix",
    "elasticity_matrix",
    "face_geometry",
    "h1_seminorm_error",
    "interpolate",
    "l2_error",
    "mass_matrix",
    "permittivity_matrix",
    "piezo_matrix",
    "strain_operator",
    "vector_dofs",
    "volume_load",
]
