"""Old home of the 3D mesh import: transitional re-export for branches in flight, issue 30;
removed when the issue closes. `body_mesh3d` is `fem.mesh_import.body_mesh` (any dimension)."""

from .mesh_import import MIRROR, VOLUME_CELLS, body_mesh

body_mesh3d = body_mesh

__all__ = ["MIRROR", "VOLUME_CELLS", "body_mesh3d"]
