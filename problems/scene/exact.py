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

The generator of the shipped manufactured scenes (2D and 3D) is `problems.scene.manufactured`.

contact3d scenes carry the same table with fields of (x, y, z) (`ExactSection3`): u, grad_u
(3 × 3), phi, grad_phi (3) and lam = λ = −σn on Γ3 as a Cartesian 3-vector (frame-free);
errors `problems.plugins.contact.solid_errors`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import Field, model_validator

from .fields import Expression, Expression3, Text, Vector, Vector3, evaluate
from .model import Section, refuse, validate
from .reader import Scene

FieldN = Callable[..., np.ndarray]  # of (x, y) in 2D, of (x, y, z) in 3D


@dataclass(frozen=True)
class Exact:
    """Compiled exact fields; each maps (x, y) arrays (3D: (x, y, z)) to x.shape + (...)."""

    u: FieldN  # → (..., d)
    grad_u: FieldN  # → (..., d, d), [k, i] = ∂u_k/∂x_i
    phi: FieldN | None  # → (...)
    grad_phi: FieldN | None  # → (..., d)
    lam: FieldN  # 2D → (..., 2): (λ·n, λ·τ) on Γ3; 3D → (..., 3): λ = −σn, Cartesian


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
        """The fields as functions of the coordinates."""
        u, rows, lam, gp = self.u, self.grad_u, self.lam, self.grad_phi

        def grad_u(*p):
            return np.stack([evaluate(r, *p) for r in rows], axis=-2)  # (..., d, d)

        return Exact(
            u=lambda *p: evaluate(u, *p),
            grad_u=grad_u,
            phi=self.phi,
            grad_phi=None if gp is None else (lambda *p: evaluate(gp, *p)),
            lam=lambda *p: evaluate(lam, *p),
        )


class ExactSection3(ExactSection):
    """The [exact] table of a contact3d scene: fields of (x, y, z), lam the Cartesian λ."""

    u: Vector3
    grad_u: Annotated[list[Vector3], Field(min_length=3, max_length=3)]
    phi: Expression3 | None = None
    grad_phi: Vector3 | None = None
    lam: Vector3


def split_exact(scene: Scene) -> tuple[Scene, Exact | None]:
    """The scene without its `[exact]` table, and the compiled table (None if absent)."""
    if "exact" not in scene.data:
        return scene, None
    data = dict(scene.data)
    raw = data.pop("exact")
    section = validate(ExactSection, raw, scene.path, scene.overrides, ("exact",))
    rest = Scene(data, scene.path, scene.name, scene.overrides, scene.notices)
    return rest, section.compiled()
