"""Bodies of a 3D contact scene: the [bodies.NAME] section with its 3D value types (the model,
its checks and the assembly into a `Body`: `problems.plugins.contact.bodies`), and the fields of the
unknowns with their near-null spaces for the iterative linear path.

A body owns 3 displacement unknowns per node and, only if its material is piezoelectric, one
potential unknown per node. Full numbering: body after body, displacement (3·N, node-major:
dof 3 i + k) then potential (N).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np

from problems.scene.fields import Expression3, Vector3
from problems.scene.geometry import Geometry3
from problems.scene.materials import MaterialSpec3

from .bodies import (
    COMPONENTS,
    Body,
    BodySection,
    DisplacementPart,
    Parts,
    ScalarPart,
    TractionPart,
)

# Quadrature order of the contact surface integrals (W, normals, g_k, the dual basis of the
# mortar): Q1 faces of a curved surface are not planar and |∂x/∂ξ × ∂x/∂η| is not polynomial
# (order 4 leaves 7e-11 in the rigid-body rows of spherical_cap, order 8 3e-15); P1 faces are
# flat (order 4 exact).
SURFACE_ORDER = {"hexahedron": 8, "tetra": 4}


class DisplacementPart3(DisplacementPart):
    """A [[displacement]] part: prescribed components of u on a boundary part (m)."""

    boundary: str
    components: Literal[tuple(COMPONENTS)] = "xyz"
    value: Vector3


class TractionPart3(TractionPart):
    """A [[traction]] part: the surface force density on a boundary part (Pa)."""

    boundary: str
    value: Vector3


class ScalarPart3(ScalarPart):
    """A [[potential]] (V) or [[charge]] (C/m²) part: a scalar field on a boundary part."""

    boundary: str
    value: Expression3


class BodySection3(BodySection):
    """One [bodies.NAME] table of a 3D scene: geometry, material, loads, boundary data."""

    POTENTIAL_WHERE = "where φ is prescribed"

    material: MaterialSpec3
    geometry: Geometry3
    body_force: Vector3 | None = None
    free_charge: Expression3 | None = None
    displacement: Annotated[list[DisplacementPart3], Parts] = []
    traction: Annotated[list[TractionPart3], Parts] = []
    potential: Annotated[list[ScalarPart3], Parts] = []
    charge: Annotated[list[ScalarPart3], Parts] = []


def field_data(bodies: list[Body], free: np.ndarray, n_full: int) -> dict:
    """`MixedVI` keywords fields and near_null: displacement and potential masks over the
    unknowns `free`, and the displacement block's six rigid-body modes (n_disp, 6)."""
    comp = np.full(n_full, -1)  # displacement component of each full dof, −1 = potential
    xyz = np.zeros((n_full, 3))  # (n_full, 3) node coordinates of each displacement dof
    for b in bodies:
        d = b.u_dofs(np.arange(b.n_nodes))  # (N, 3)
        comp[d] = np.arange(3)[None, :]
        for k in range(3):
            xyz[d[:, k]] = b.mesh.points
    c, p = comp[free], xyz[free]  # (n,), (n, 3)
    disp = c >= 0
    modes = np.zeros((free.size, 6))  # translations x, y, z; rotations about x, y, z
    for k in range(3):
        modes[c == k, k] = 1.0
    for r, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):  # rotation about axis r: (−x_j, x_i)
        modes[c == i, 3 + r] = -p[c == i, j]
        modes[c == j, 3 + r] = p[c == j, i]
    fields = {"displacement": disp}
    if (~disp).any():
        fields["potential"] = ~disp
    return {"fields": fields, "near_null": {"displacement": modes[disp]}}
