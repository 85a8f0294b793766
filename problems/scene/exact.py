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

contact3d scenes carry the same table with fields of (x, y, z) (`ExactSection3`): u, grad_u
(3 × 3), phi, grad_phi (3) and lam = λ = −σn on Γ3 as a Cartesian 3-vector (frame-free);
generator `problems.scene.manufactured3d`, errors `problems.plugins.contact3d_errors`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import Field, model_validator

from .fields import Expression, Text, Vector, evaluate
from .fields3d import Expression3, Vector3
from .model import Section, refuse, validate
from .reader import Scene

Field2 = Callable[[np.ndarray, np.ndarray], np.ndarray]
Field3 = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


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
        return _phi_pair(self)

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


def _phi_pair(section):
    """Refuse a table with only one of phi and grad_phi."""
    if (section.phi is None) != (section.grad_phi is None):
        raise refuse(
            ["phi"], section.phi and section.phi.source, "both phi and grad_phi, or neither"
        )
    return section


@dataclass(frozen=True)
class Exact3:
    """Compiled exact fields of a 3D scene; each maps (x, y, z) arrays to x.shape + (...)."""

    u: Field3  # → (..., 3)
    grad_u: Field3  # → (..., 3, 3), [k, i] = ∂u_k/∂x_i
    phi: Field3 | None  # → (...)
    grad_phi: Field3 | None  # → (..., 3)
    lam: Field3  # → (..., 3): λ = −σn on Γ3, Cartesian


class ExactSection3(Section):
    """The [exact] table of a contact3d scene (fields of x, y, z)."""

    source: Text = ""
    u: Vector3
    grad_u: Annotated[list[Vector3], Field(min_length=3, max_length=3)]
    phi: Expression3 | None = None
    grad_phi: Vector3 | None = None
    lam: Vector3

    @model_validator(mode="after")
    def _phi_pair(self) -> ExactSection3:
        return _phi_pair(self)

    def compiled(self) -> Exact3:
        """The fields as functions of (x, y, z)."""
        u, rows, lam, gp = self.u, self.grad_u, self.lam, self.grad_phi

        def grad_u(x, y, z):
            return np.stack([evaluate(r, x, y, z) for r in rows], axis=-2)  # (..., 3, 3)

        return Exact3(
            u=lambda x, y, z: evaluate(u, x, y, z),
            grad_u=grad_u,
            phi=self.phi,
            grad_phi=None if gp is None else (lambda x, y, z: evaluate(gp, x, y, z)),
            lam=lambda x, y, z: evaluate(lam, x, y, z),
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
