"""Transitional re-export for branches in flight, issue 30; removed when the issue closes."""

from .materials import Isotropic3, MaterialSpec3, NamedMaterial3

__all__ = ["Isotropic3", "MaterialSpec3", "NamedMaterial3"]
