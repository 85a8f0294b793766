"""Bodies of a 3D contact scene: the [bodies.NAME] section model and its assembly
(geometry → `Mesh3D`, material tensors, loads, Dirichlet data), and the fields of the unknowns
with their near-null spaces for the iterative linear path.

A body owns 3 displacement unknowns per node and, only if its material is piezoelectric, one
potential unknown per node. Full numbering: body after body, displacement (3·N, node-major:
dof 3 i + k) then potential (N).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
import scipy.sparse as sp
from pydantic import BeforeValidator, model_validator

from fem import assembly3d
from fem.mesh3d import Mesh3D
from fem.tensors import Material3D
from problems.scene import Section
from problems.scene.fields3d import Expression3, Vector3, evaluate3
from problems.scene.geometry3d import Geometry3
from problems.scene.materials3d import MaterialSpec3
from problems.scene.model import one_or_many, refuse

from .contract import check_boundaries

# Quadrature order of the contact surface integrals (W, normals, g_k, the dual basis of the
# mortar): Q1 faces of a curved surface are not planar and |∂x/∂ξ × ∂x/∂η| is not polynomial
# (order 4 leaves 7e-11 in the rigid-body rows of spherical_cap, order 8 3e-15); P1 faces are
# flat (order 4 exact).
SURFACE_ORDER = {"hexahedron": 8, "tetra": 4}
COMPONENTS = {c: tuple("xyz".index(a) for a in c) for c in ("x", "y", "z", "xy", "xz", "yz", "xyz")}


def vector3(components: list[Expression3]):
    """A vector field as one function (x, y, z) → (..., 3)."""
    return lambda x, y, z: evaluate3(components, x, y, z)


@dataclass
class Body3D:
    """One 3D body: mesh, material, full-numbering offset and its assembled blocks."""

    name: str
    mesh: Mesh3D
    material: Material3D
    offset: int  # first full dof of this body
    A: sp.csr_matrix = None  # (n_b, n_b): [[K, Gᵀ], [−G, P]] or K
    f: np.ndarray = None  # (n_b,)
    fixed: np.ndarray = None  # (n_b,) bool
    values: np.ndarray = None  # (n_b,) prescribed values on fixed dofs
    X: sp.csr_matrix = None  # (n_b, n_b) H1 Gram matrix of the body's fields

    @property
    def n_nodes(self) -> int:
        """Nodes of the mesh."""
        return self.mesh.n_nodes

    @property
    def has_potential(self) -> bool:
        """Whether the body has potential unknowns (a piezoelectric material)."""
        return self.material.piezoelectric

    @property
    def size(self) -> int:
        """Full dofs of the body."""
        return self.n_nodes * (4 if self.has_potential else 3)

    def u_dofs(self, nodes: np.ndarray) -> np.ndarray:
        """Full indices (len(nodes), 3) of the displacement dofs of `nodes`."""
        nodes = np.asarray(nodes)
        return self.offset + 3 * nodes[:, None] + np.arange(3)[None, :]

    def split(self, x_body: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Body-local full vector → displacement (N, 3) and potential (N,) or None."""
        N = self.n_nodes
        return x_body[: 3 * N].reshape(N, 3), (x_body[3 * N :] if self.has_potential else None)


Parts = BeforeValidator(one_or_many)


class DisplacementPart3(Section):
    """A [[displacement]] part: prescribed components of u on a boundary part (m)."""

    boundary: str
    components: Literal[tuple(COMPONENTS)] = "xyz"
    value: Vector3


class TractionPart3(Section):
    """A [[traction]] part: the surface force density on a boundary part (Pa)."""

    boundary: str
    value: Vector3


class ScalarPart3(Section):
    """A [[potential]] (V) or [[charge]] (C/m²) part: a scalar field on a boundary part."""

    boundary: str
    value: Expression3


class BodySection3(Section):
    """One [bodies.NAME] table of a 3D scene: geometry, material, loads, boundary data."""

    material: MaterialSpec3
    geometry: Geometry3
    body_force: Vector3 | None = None
    free_charge: Expression3 | None = None
    displacement: Annotated[list[DisplacementPart3], Parts] = []
    traction: Annotated[list[TractionPart3], Parts] = []
    potential: Annotated[list[ScalarPart3], Parts] = []
    charge: Annotated[list[ScalarPart3], Parts] = []

    @model_validator(mode="after")
    def _consistent(self) -> BodySection3:
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
                "at least one [[potential]] part (where φ is prescribed): the material "
                f"{material.name!r} is piezoelectric",
            )
        if not material.piezoelectric:
            for key in ("potential", "charge", "free_charge"):
                v = getattr(self, key)
                if v:
                    raise refuse(
                        [key],
                        v.source if isinstance(v, Expression3) else [p.boundary for p in v],
                        f"not allowed: the material {material.name!r} is not piezoelectric, so "
                        "the body has no electric potential",
                    )
        return self


def build_body3(name: str, t: BodySection3, level: int, offset: int) -> Body3D:
    """Mesh one validated [bodies.NAME] table and assemble the body's blocks."""
    mesh = t.geometry.mesh(level)
    body = Body3D(name, mesh, t.material.material(), offset)
    material = body.material
    N = mesh.n_nodes
    f = np.zeros(body.size)
    fixed, values = dirichlet3(t, body)
    if t.body_force is not None:
        f[: 3 * N] += assembly3d.volume_load(mesh, vector3(t.body_force), 3)
    for tt in t.traction:
        f[: 3 * N] += assembly3d.boundary_load(mesh, tt.boundary, vector3(tt.value), 3)
    K = assembly3d.elasticity_matrix(mesh, material.C)
    H1 = (assembly3d.mass_matrix(mesh) + assembly3d.permittivity_matrix(mesh, np.eye(3))).tocsr()
    X_blocks = [sp.kron(H1, sp.identity(3)).tocsr()]  # node-major: dof 3 i + k ↔ (i, k)
    if material.piezoelectric:
        G = assembly3d.coupling_matrix(mesh, material.e)
        P = assembly3d.permittivity_matrix(mesh, material.kappa)
        A = sp.bmat([[K, G.T], [-G, P]], format="csr")
        fphi = np.zeros(N)
        if t.free_charge is not None:
            fphi += assembly3d.volume_load(mesh, t.free_charge, 1)
        for tt in t.charge:
            fphi -= assembly3d.boundary_load(mesh, tt.boundary, tt.value, 1)
        f[3 * N :] = fphi
        X_blocks.append(H1)
    else:
        A = K.tocsr()
    body.A, body.f, body.fixed, body.values = A, f, fixed, values
    body.X = sp.block_diag(X_blocks, format="csr")
    return body


def dirichlet3(t: BodySection3, body: Body3D) -> tuple[np.ndarray, np.ndarray]:
    """(fixed (n_b,) bool, values (n_b,)) of the body's prescribed displacement components and
    potentials (body-local full numbering; values 0 where free)."""
    mesh, N = body.mesh, body.n_nodes
    fixed = np.zeros(body.size, dtype=bool)
    values = np.zeros(body.size)
    for tt in t.displacement:
        nodes = mesh.boundary_nodes(tt.boundary)
        P = mesh.points[nodes]
        val = evaluate3(tt.value, P[:, 0], P[:, 1], P[:, 2])  # (k, 3)
        for c in COMPONENTS[tt.components]:
            fixed[3 * nodes + c] = True
            values[3 * nodes + c] = val[:, c]
    if body.has_potential:
        for tt in t.potential:
            nodes = mesh.boundary_nodes(tt.boundary)
            P = mesh.points[nodes]
            fixed[3 * N + nodes] = True
            values[3 * N + nodes] = tt.value(P[:, 0], P[:, 1], P[:, 2])
    return fixed, values


def count3(t: BodySection3, body: Body3D) -> tuple[int, int]:
    """(free unknowns, stored entries of the body's reduced operator) without assembling it:
    every pair of nodes sharing a cell couples all their free unknowns (the assembly stores
    full blocks on the cell pattern, explicit zeros included)."""
    fixed, _ = dirichlet3(t, body)
    N = body.n_nodes
    d = (~fixed[: 3 * N]).reshape(N, 3).sum(axis=1)  # (N,) free unknowns per node
    if body.has_potential:
        d = d + ~fixed[3 * N :]
    cells = body.mesh.cells  # (n_cells, n_loc)
    k = cells.shape[1]
    rows = np.repeat(cells, k, axis=1).ravel()
    cols = np.tile(cells, (1, k)).ravel()
    P = sp.csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(N, N))
    P.sum_duplicates()
    P.data[:] = 1
    return int(d.sum()), int(d @ (P @ d.astype(np.int64)))


def field_data3(bodies: list[Body3D], free: np.ndarray, n_full: int) -> dict:
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
