"""Transitional re-export for branches in flight, issue 30; removed when the issue closes."""

from .fields import Cells3, Direction, Expression3, Interval, NonNegativeExpr3, Vector3

__all__ = ["Cells3", "Direction", "Expression3", "Interval", "NonNegativeExpr3", "Vector3"]
