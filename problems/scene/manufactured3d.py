"""Transitional re-export for branches in flight, issue 30; removed when the issue closes."""

from .manufactured import BOX, CENTRE, S0, SIDES

__all__ = ["BOX", "CENTRE", "S0", "SIDES"]
