"""Old home of the 3D meshes: transitional re-export for branches in flight, issue 30; removed
when the issue closes. `Mesh3D` is `fem.mesh.Mesh` (any dimension)."""

from .elements import EDGES
from .jacobians import check_cells, cofactors, jacobian_determinants
from .mesh import Mesh, exterior_facets
from .meshing import END_PARTS, SIDES, box, extrude, transform
from .refine import refine

Mesh3D = Mesh
exterior_faces = exterior_facets

__all__ = [
    "EDGES",
    "END_PARTS",
    "SIDES",
    "Mesh3D",
    "box",
    "check_cells",
    "cofactors",
    "exterior_faces",
    "extrude",
    "jacobian_determinants",
    "refine",
    "transform",
]
