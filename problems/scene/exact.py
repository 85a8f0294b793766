"""Exact solutions of scenes: the `[exact]` table.

A scene may carry an `[exact]` table of expression fields (same safe expressions as every scene
value) giving the exact solution:

    [exact]
    u = [u1, u2]                          # displacement (m)
    grad_u = [[u1_x, u1_y], [u2_x, u2_y]]
    phi = "..."                           # potential (V), piezoelectric bodies
    grad_phi = [phi_x, phi_y]
    lam = [lam_n, lam_t]                  # λ = −σn on Γ3: λ·n and λ·τ (Pa), fields of (x, y)

`split_exact` removes the table from the scene (the plug-in does not know the key) and compiles
it. The study engine (`problems.commands.study`) measures errors against it.

The generator of the shipped manufactured scene is `problems.scene.manufactured`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from problems.errors import SceneError

from .reader import Scene, Table

# ------------------------------------------------------------------ the [exact] table
Field = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Exact:
    """Compiled exact fields; each maps (x, y) arrays to x.shape + (components...)."""

    u: Field  # → (..., 2)
    grad_u: Field  # → (..., 2, 2), [k, i] = ∂u_k/∂x_i
    phi: Field | None  # → (...)
    grad_phi: Field | None  # → (..., 2)
    lam: Field  # → (..., 2): (λ·n, λ·τ) on Γ3


def _matrix_field(t: Table, name: str) -> Field:
    """A 2×2 list of expression fields as one function → (..., 2, 2)."""
    raw = t.raw(name)
    if not (isinstance(raw, list) and len(raw) == 2 and all(isinstance(r, list) for r in raw)):
        raise SceneError(t.key(name), raw, "a 2×2 list [[a, b], [c, d]] of numbers or expressions")
    rows = [Table({"row": r}, t.key(name)).field("row", 2) for r in raw]

    def fn(x, y):
        return np.stack([r(x, y) for r in rows], axis=-2)  # (..., 2, 2)

    return fn


def split_exact(scene: Scene) -> tuple[Scene, Exact | None]:
    """The scene without its `[exact]` table, and the compiled table (None if absent)."""
    if "exact" not in scene.data:
        return scene, None
    data = dict(scene.data)
    raw = data.pop("exact")
    if not isinstance(raw, dict):
        raise SceneError("exact", raw, "a table [exact] with u, grad_u, lam (and phi, grad_phi)")
    t = Table(raw, "exact")
    exact = Exact(
        u=t.field("u", 2),
        grad_u=_matrix_field(t, "grad_u"),
        phi=t.field("phi", 1) if t.has("phi") else None,
        grad_phi=t.field("grad_phi", 2) if t.has("grad_phi") else None,
        lam=t.field("lam", 2),
    )
    if (exact.phi is None) != (exact.grad_phi is None):
        raise SceneError("exact", sorted(raw), "both phi and grad_phi, or neither")
    t.finish()
    return Scene(data=data, path=scene.path, name=scene.name), exact
