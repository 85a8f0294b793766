"""The contact law of a [contact] table, shared by the contact plug-in's fronts `plane` (2D,
signorini's preset too) and `solid` (3D): the keys, their validation and the multiplier set
they make.

    law = "bilateral"    the bodies stay in contact, λ_n of any sign (the paper's model)
          "unilateral"   λ_n ≥ 0, gap ≥ 0, λ_n·gap = 0
    friction = "tresca"  bound g (a field ≥ 0, Pa); with law = "unilateral" it acts only where
                         the bodies touch
               "coulomb" bound F·λ_n (F a field ≥ 0); unilateral only
    gap                  the initial normal distance to a rigid foundation (m, a field ≥ 0);
                         unilateral only; two bodies take theirs from the geometry

Exactly the key of the chosen friction (g or F) is given. The tables are the same in 2D and
3D (fields of x, y or x, y, z): `FrictionLaw` and `ContactLaw`; `pair_set` the vi_core set of
the nodes that carry [λ_n, λ_t] (docs/coulomb.md, "Contact laws of the plug-ins").
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import model_validator

from problems.scene import Section
from problems.scene.fields import NonNegativeExpr
from problems.scene.model import refuse
from vi_core import Coulomb, UnilateralTresca
from vi_core.coulomb import ContactSet

LAWS = ("bilateral", "unilateral")  # [contact] law
FRICTIONS = ("tresca", "coulomb")  # [contact] friction


class FrictionLaw(Section):
    """The friction of a contact table: friction = "tresca" (bound g, a field ≥ 0 in Pa) or
    "coulomb" (bound F·λ_n, F a field ≥ 0); exactly the key of the chosen friction is given."""

    friction: Literal[FRICTIONS] = FRICTIONS[0]
    g: NonNegativeExpr | None = None
    F: NonNegativeExpr | None = None

    @model_validator(mode="after")
    def _friction(self) -> FrictionLaw:
        need, other = ("g", "F") if self.friction == "tresca" else ("F", "g")
        if getattr(self, need) is None:
            raise refuse([need], None, f"required with friction = {self.friction!r}")
        if getattr(self, other) is not None:
            allowed = f"absent with friction = {self.friction!r}"
            raise refuse([other], getattr(self, other).source, allowed)
        return self


class ContactLaw(FrictionLaw):
    """The contact-law keys (module docstring): law = "bilateral" or "unilateral"; friction =
    "tresca" (g) or "coulomb" (F, unilateral only); gap = the initial normal distance to a
    rigid foundation (unilateral only; two bodies take theirs from the geometry). The plug-in's
    [contact] table subclasses it with its slave and master keys."""

    law: Literal[LAWS] = LAWS[0]
    gap: NonNegativeExpr | None = None

    @model_validator(mode="after")
    def _law(self) -> ContactLaw:
        gap = None if self.gap is None else self.gap.source
        if self.law == "bilateral" and self.friction == "coulomb":
            raise refuse(["friction"], "coulomb", "'tresca' with law = 'bilateral'")
        if self.law == "bilateral" and gap is not None:
            raise refuse(["gap"], gap, "absent with law = 'bilateral'")
        if gap is not None and getattr(self, "master", "rigid") != "rigid":
            raise refuse(["gap"], gap, "absent for two bodies (their gap is the geometry's)")
        return self


def pair_set(friction: str, bound: np.ndarray, dim: int) -> ContactSet:
    """The vi_core set of unilateral contact nodes [λ_n, λ_t] in R^dim (dim = 2: one tangent,
    dim = 3: a friction disc): Coulomb(F = bound) or contact-only UnilateralTresca(g = bound)."""
    if friction == "coulomb":
        return Coulomb(bound, dim=dim)
    return UnilateralTresca(bound, dim=dim, contact_only=True)
