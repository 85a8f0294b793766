"""Bodies of a contact scene: the [bodies.NAME] section model, and its assembly
(geometry → mesh, material, loads, Dirichlet data).

A body owns its displacement unknowns and, only if its material is piezoelectric, its
potential unknowns. Global (full) numbering: body after body, displacement (2·N, node-major)
then potential (N).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
import scipy.sparse as sp
from pydantic import BeforeValidator, model_validator

from fem import assembly
from fem.mesh import Mesh
from problems.scene import Section
from problems.scene.fields import Expression, Text, Vector, evaluate
from problems.scene.geometry import Geometry
from problems.scene.materials import Material, MaterialSpec
from problems.scene.model import one_or_many, refuse

from .contract import check_boundaries, check_meshed

COMPONENTS = {"x": (0,), "y": (1,), "xy": (0, 1)}


def vector(components: list[Expression]):
    """A vector field as one function (x, y) → (..., 2)."""
    return lambda x, y: evaluate(components, x, y)


@dataclass
class Body:
    """One body: mesh, material, full-numbering offsets and its assembled blocks."""

    name: str
    mesh: Mesh
    material: Material
    offset: int  # first full dof of this body
    A: sp.csr_matrix = None  # (n_b, n_b): [[K, Gᵀ], [−G, P]] or K
    f: np.ndarray = None  # (n_b,)
    fixed: np.ndarray = None  # (n_b,) bool
    values: np.ndarray = None  # (n_b,) prescribed values on fixed dofs
    X: sp.csr_matrix = None  # (n_b, n_b) H1 Gram matrix of the body's fields

    @property
    def n_nodes(self) -> int:
        return self.mesh.n_nodes

    @property
    def has_potential(self) -> bool:
        return self.material.piezoelectric

    @property
    def size(self) -> int:
        return self.n_nodes * (3 if self.has_potential else 2)

    def u_dofs(self, nodes: np.ndarray) -> np.ndarray:
        """Full indices (len(nodes), 2) of the displacement dofs of `nodes`."""
        nodes = np.asarray(nodes)
        return self.offset + 2 * nodes[:, None] + np.arange(2)[None, :]

    def phi_dofs(self, nodes: np.ndarray) -> np.ndarray:
        """Full indices of the potential dofs of `nodes` (piezoelectric bodies only)."""
        return self.offset + 2 * self.n_nodes + np.asarray(nodes)

    def split(self, x_body: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Body-local full vector → displacement (N, 2) and potential (N,) or None."""
        N = self.n_nodes
        u = x_body[: 2 * N].reshape(N, 2)
        phi = x_body[2 * N :] if self.has_potential else None
        return u, phi


Parts = BeforeValidator(one_or_many)


class DisplacementPart(Section):
    """A [[displacement]] part: prescribed components of u on a boundary part."""

    boundary: Text
    components: Literal["x", "y", "xy"] = "xy"
    value: Vector


class TractionPart(Section):
    """A [[traction]] part: the surface force density on a boundary part (Pa)."""

    boundary: Text
    value: Vector


class ScalarPart(Section):
    """A [[potential]] or [[charge]] part: a scalar field on a boundary part."""

    boundary: Text
    value: Expression


class BodySection(Section):
    """One [bodies.NAME] table (and signorini's [body]): geometry, material, loads, data."""

    material: MaterialSpec
    geometry: Geometry
    body_force: Vector | None = None
    free_charge: Expression | None = None
    displacement: Annotated[list[DisplacementPart], Parts] = []
    traction: Annotated[list[TractionPart], Parts] = []
    potential: Annotated[list[ScalarPart], Parts] = []
    charge: Annotated[list[ScalarPart], Parts] = []

    def boundary_refs(self) -> list[tuple[str, str]]:
        """(field path, boundary name) of every boundary this table names."""
        return [
            (part.key("boundary"), part.boundary)
            for key in ("displacement", "traction", "potential", "charge")
            for part in getattr(self, key)
        ]

    @model_validator(mode="after")
    def _consistent(self) -> BodySection:
        names = self.geometry.BOUNDARIES
        for key in ("displacement", "traction", "potential", "charge"):
            for i, part in enumerate(getattr(self, key)):
                check_boundaries([key, i, "boundary"], [part.boundary], names)
        if not self.displacement:
            raise refuse(
                ["displacement"],
                [],
                "at least one [[displacement]] part (otherwise a rigid motion is left free)",
            )
        material = self.material.material()
        if material.piezoelectric and not self.potential:
            raise refuse(
                ["potential"],
                None,
                "at least one [[potential]] part (Γ_a, where φ is prescribed): the material "
                f"{material.name!r} is piezoelectric",
            )
        if not material.piezoelectric:
            for key in ("potential", "charge", "free_charge"):
                v = getattr(self, key)
                if v:
                    raise refuse(
                        [key],
                        v.source if isinstance(v, Expression) else [p.boundary for p in v],
                        f"not allowed: the material {material.name!r} is not piezoelectric, so "
                        "the body has no electric potential",
                    )
        return self


def build_body(name: str, t: BodySection, level: int, offset: int) -> Body:
    """Mesh one validated `[bodies.NAME]` table and assemble the body's blocks (the boundary
    references checked now if the geometry's parts are known only once meshed)."""
    mesh = t.geometry.mesh(level)
    if t.geometry.BOUNDARIES is None:
        check_meshed(mesh, t.boundary_refs())
    material = t.material.material()
    body = Body(name, mesh, material, offset)
    N = mesh.n_nodes
    n_b = body.size
    K = assembly.elasticity_matrix(mesh, material.C)
    f = np.zeros(n_b)
    fixed = np.zeros(n_b, dtype=bool)
    values = np.zeros(n_b)
    if t.body_force is not None:
        f[: 2 * N] += assembly.volume_load(mesh, vector(t.body_force), 2)
    for tt in t.traction:
        f[: 2 * N] += assembly.boundary_load(mesh, tt.boundary, vector(tt.value), 2)
    for tt in t.displacement:
        comps = COMPONENTS[tt.components]
        nodes = mesh.boundary_nodes(tt.boundary)
        val = evaluate(tt.value, mesh.points[nodes, 0], mesh.points[nodes, 1])  # (k, 2)
        for c in comps:
            fixed[2 * nodes + c] = True
            values[2 * nodes + c] = val[:, c]
    Mu = assembly.mass_matrix(mesh)
    Su = assembly.stiffness_matrix(mesh)
    H1 = (Mu + Su).tocsr()
    X_blocks = [sp.kron(H1, sp.identity(2)).tocsr()]  # node-major: dof 2·i + k ↔ (i, k)
    if material.piezoelectric:
        G = assembly.coupling_matrix(mesh, material.e)
        P = assembly.permittivity_matrix(mesh, material.kappa)
        A = sp.bmat([[K, G.T], [-G, P]], format="csr")
        fphi = np.zeros(N)
        if t.free_charge is not None:
            fphi += assembly.volume_load(mesh, t.free_charge, 1)
        for tt in t.charge:
            fphi -= assembly.boundary_load(mesh, tt.boundary, tt.value, 1)
        f[2 * N :] = fphi
        for tt in t.potential:
            nodes = mesh.boundary_nodes(tt.boundary)
            fixed[2 * N + nodes] = True
            values[2 * N + nodes] = tt.value(mesh.points[nodes, 0], mesh.points[nodes, 1])
        X_blocks.append(H1)
    else:
        A = K.tocsr()
    body.A, body.f, body.fixed, body.values = A, f, fixed, values
    body.X = sp.block_diag(X_blocks, format="csr")
    return body
