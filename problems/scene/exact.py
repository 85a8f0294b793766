"""Exact solutions of contact scenes: the `[exact]` table of contact scenes, 2D or 3D.

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

A 3D scene's table has fields of (x, y, z): u, grad_u (3 × 3), phi, grad_phi (3) and
lam = λ = −σn on Γ3 as a Cartesian 3-vector (frame-free); errors
`problems.plugins.contact.errors`. The table's dimension is that of u (`dim`); the other
fields are checked against it here, and it against the bodies' by the scene.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import Field, ValidationInfo, model_validator

from .fields import Expression, Text, Vector, evaluate, renamed
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
    """The [exact] table of a contact scene (2D or 3D: d = the length of u)."""

    source: Text = ""
    u: Vector
    grad_u: Annotated[list[Vector], Field(min_length=2, max_length=3)]
    phi: Expression | None = None
    grad_phi: Vector | None = None
    lam: Vector

    @property
    def dim(self) -> int:
        """The dimension of the table's fields: u's number of components."""
        return len(self.u)

    @model_validator(mode="after")
    def _shapes(self, info: ValidationInfo) -> ExactSection:
        if (self.phi is None) != (self.grad_phi is None):
            raise refuse(["phi"], self.phi and self.phi.source, "both phi and grad_phi, or neither")
        d, scene_dim, written = self.dim, (info.context or {}).get("dimension"), self.model_dump()
        if scene_dim not in (None, d):
            allowed = f"{scene_dim} entries: the scene is {scene_dim}D (its geometries are)"
            raise refuse(["u"], written["u"], allowed)
        rows = written["grad_u"]
        fields = [(["grad_u"], rows, f"{d} rows, one per component of u")]
        fields += [(["grad_u", i], r, f"{d} entries, one per axis") for i, r in enumerate(rows)]
        fields += [([k], written[k], f"{d} entries, as u") for k in ("grad_phi", "lam")]
        for loc, value, allowed in fields:
            if value is not None and len(value) != d:
                raise refuse(loc, value, allowed)
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


def split_exact(scene: Scene) -> tuple[Scene, Exact | None]:
    """The scene without its `[exact]` table, and the compiled table (None if absent)."""
    if "exact" not in scene.data:
        return scene, None
    data = dict(scene.data)
    raw = data.pop("exact")
    section = validate(ExactSection, raw, scene.path, scene.overrides, ("exact",))
    rest = Scene(data, scene.path, scene.name, scene.overrides, scene.notices)
    return rest, section.compiled()


__getattr__ = renamed(__name__, {"ExactSection3": "ExactSection"})  # the former 3D names
