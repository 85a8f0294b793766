"""Exact solutions of contact scenes: the `[exact]` table of piezo_contact scenes.

A scene may carry an `[exact]` table of expression fields (same safe expressions as every scene
value) giving the exact solution:

    [exact]
    u = [u1, u2]                          # displacement (m)
    grad_u = [[u1_x, u1_y], [u2_x, u2_y]]
    phi = "..."                           # potential (V), piezoelectric bodies
    grad_phi = [phi_x, phi_y]
    lam = [lam_n, lam_t]                  # λ = −σn on Γ3: λ·n and λ·τ (Pa), fields of (x, y)

`ExactSection` is its scene model (validated with the rest of the scene); `split_exact` removes
the table from a scene and compiles it. The study engine measures errors against it.

The generator of the shipped manufactured scene is `problems.scene.manufactured`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import Field, model_validator

from .fields import Expression, Text, Vector, evaluate
from .model import Section, refuse, validate
from .reader import Scene

Field2 = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Exact:
    """Compiled exact fields; each maps (x, y) arrays to x.shape + (components...)."""

    u: Field2  # → (..., 2)
    grad_u: Field2  # → (..., 2, 2), [k, i] = ∂u_k/∂x_i
    phi: Field2 | None  # → (...)
    grad_phi: Field2 | None  # → (..., 2)
    lam: Field2  # → (..., 2): (λ·n, λ·τ) on Γ3


class ExactSection(Section):
    """The [exact] table of a contact scene."""

    source: Text = ""
    u: Vector
    grad_u: Annotated[list[Vector], Field(min_length=2, max_length=2)]
    phi: Expression | None = None
    grad_phi: Vector | None = None
    lam: Vector

    @model_validator(mode="after")
    def _phi_pair(self) -> ExactSection:
        if (self.phi is None) != (self.grad_phi is None):
            raise refuse(["phi"], self.phi and self.phi.source, "both phi and grad_phi, or neither")
        return self

    def compiled(self) -> Exact:
        """The fields as functions of (x, y)."""
        u, rows, lam, gp = self.u, self.grad_u, self.lam, self.grad_phi

        def grad_u(x, y):
            return np.stack([evaluate(r, x, y) for r in rows], axis=-2)  # (..., 2, 2)

        return Exact(
            u=lambda x, y: evaluate(u, x, y),
            grad_u=grad_u,
            phi=self.phi,
            grad_phi=None if gp is None else (lambda x, y: evaluate(gp, x, y)),
            lam=lambda x, y: evaluate(lam, x, y),
        )


def split_exact(scene: Scene) -> tuple[Scene, Exact | None]:
    """The scene without its `[exact]` table, and the compiled table (None if absent)."""
    if "exact" not in scene.data:
        return scene, None
    data = dict(scene.data)
    raw = data.pop("exact")
    section = validate(ExactSection, raw, scene.path, scene.overrides, ("exact",))
    rest = Scene(data, scene.path, scene.name, scene.overrides, scene.notices)
    return rest, section.compiled()
