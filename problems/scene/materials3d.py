"""Materials of 3D scenes: full Voigt tensors (`fem.tensors.Material3D`).

A scene's `material` is a name of `problems.scene.materials.NAMED` (the same constants as the
2D scenes, so that a 3D scene extruded from a 2D one solves the same problem), optionally with
the poling direction (`{ name = "BaTiO3", poling = [0, 1, 0] }`, default z) and a scaled
coupling, or `{ kind = "isotropic", E = ..., nu = ... }`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BeforeValidator, Discriminator, Field, Tag

from fem.tensors import Material3D, crystal_6mm, isotropic, poled

from .fields import Number, Text
from .fields3d import Direction
from .materials import MATERIAL_NAMES, MAX_COUPLING, NAMED
from .model import Section


def named_6mm(name: str) -> Material3D:
    """The 6mm crystal `name` of the 2D table NAMED, poled along z."""
    d = {k: np.asarray(v, float) for k, v in NAMED[name].items()}
    C, e, k = d["C"], d["e"], d["kappa"]
    return crystal_6mm(
        name,
        C[0, 0],
        d["C_zz"][0],
        C[0, 1],
        C[1, 1],
        C[2, 2],
        e[1, 0],
        e[1, 1],
        e[0, 2],
        k[0, 0],
        k[1, 1],
    )


class NamedMaterial3(Section):
    """A named 6mm piezoelectric crystal poled along `poling`, its coupling optionally scaled."""

    name: Literal[MATERIAL_NAMES]
    poling: Direction = [0.0, 0.0, 1.0]
    coupling_scale: Annotated[Number, Field(gt=0.0, lt=MAX_COUPLING)] = 1.0

    def material(self) -> Material3D:
        """The constitutive data."""
        m = poled(named_6mm(self.name), self.poling)
        label = (
            self.name
            if self.coupling_scale == 1.0
            else f"{self.name} (coupling ×{self.coupling_scale:g})"
        )
        return Material3D(label, m.C, self.coupling_scale * m.e, m.kappa)


class Isotropic3(Section):
    """Linear isotropic elasticity from Young's modulus E and Poisson's ratio ν."""

    kind: Literal["isotropic"]
    E: Annotated[Number, Field(gt=0.0)]
    nu: Annotated[Number, Field(gt=-1.0, lt=0.5)]
    label: Text = "isotropic"

    def material(self) -> Material3D:
        """The constitutive data."""
        return isotropic(self.E, self.nu, self.label)


def _tag(v: Any) -> str | None:
    if isinstance(v, str) or (isinstance(v, dict) and "name" in v):
        return "named"
    if isinstance(v, dict):
        return v.get("kind") if isinstance(v.get("kind"), str) else None
    if isinstance(v, Section):
        return "named" if isinstance(v, NamedMaterial3) else "isotropic"
    return None


MaterialSpec3 = Annotated[
    Annotated[NamedMaterial3, Tag("named")] | Annotated[Isotropic3, Tag("isotropic")],
    Discriminator(
        _tag,
        custom_error_type="material",
        custom_error_message="a material name (" + ", ".join(sorted(NAMED)) + ") or a table "
        "with name = NAME (and poling = [dx, dy, dz]) or kind = isotropic",
    ),
    BeforeValidator(lambda v: {"name": v} if isinstance(v, str) else v),
]
