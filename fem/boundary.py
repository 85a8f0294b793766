"""Transitional re-export for branches in flight, issue 30; removed when the issue closes.

The 2D traces moved to `fem.facets` (one trace type for 2D and 3D)."""

from .facets import ENDS, Trace, dual_mass, multiplier_basis, trace
from .facets import facet_integrals as segment_loads

__all__ = ["ENDS", "Trace", "dual_mass", "multiplier_basis", "segment_loads", "trace"]
