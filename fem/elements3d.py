"""Transitional re-export for branches in flight, issue 30; removed when the issue closes.

The 3D reference elements now live in `fem.elements` with the 2D ones.
"""

from .elements import CELL_TYPES as _CELL_TYPES
from .elements import FACET_TYPE as FACE_TYPE
from .elements import FACETS as FACES
from .elements import ReferenceElement as ReferenceElement3D
from .elements import reference_element as reference_element3d

CELL_TYPES = _CELL_TYPES[3]

__all__ = ["CELL_TYPES", "FACES", "FACE_TYPE", "ReferenceElement3D", "reference_element3d"]
