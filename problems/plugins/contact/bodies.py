"""Bodies of a contact scene: the [bodies.NAME] section model, and its assembly
(geometry → mesh, material, loads, Dirichlet data), in 2D and in 3D, the fields of the
unknowns with their near-null spaces for the iterative linear path (`field_data`).

A body's geometry decides its dimension d (`BodySection.dim`); its vectors, displacement
components and material matrices are checked against d where the table is validated.

A body owns d displacement unknowns per node (d = 2 or 3, the mesh's dimension) and, only if
its material is piezoelectric, one potential unknown per node. Global (full) numbering: body
after body, displacement (d·N, node-major: dof d·i + k) then potential (N).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
import scipy.sparse as sp
from pydantic import BeforeValidator, Field, ValidationInfo, model_validator

from fem import assembly
from fem.mesh import Mesh
from fem.refined_counts import Skeleton
from fem.tensors import Material3D
from problems.scene import Section
from problems.scene.fields import Expression, Text, Vector, evaluate
from problems.scene.geometry import Geometry, wrong_dimension
from problems.scene.materials import Material, MaterialSpec
from problems.scene.model import one_or_many, refuse
from vi_core.engine import row_partition

from ..contract import check_boundaries, check_meshed, prescribed_once
from .interface import Gone

# the displacement components a [[displacement]] part may prescribe → their indices
COMPONENTS = {c: tuple("xyz".index(a) for a in c) for c in ("x", "y", "z", "xy", "xz", "yz", "xyz")}


def vector(components: list[Expression]):
    """A vector field as one function (x, y[, z]) → (..., len(components))."""
    return lambda *coords: evaluate(components, *coords)


def coordinates(mesh: Mesh, nodes: np.ndarray) -> list[np.ndarray]:
    """The coordinate arrays x, y[, z], each (len(nodes),), of `nodes`."""
    return [mesh.points[nodes, i] for i in range(mesh.points.shape[1])]


# the fields of the former 3D `SolidContact.master` (an `interface.Coupling`) that a Body lacks
# and `Interface.coupling` still has (its n_cells went in 4587fd3: no hint sends users there)
COUPLING_NAMES = {"body", "part", "M_loc", "dofs", "covered", "patch_defect"}


@dataclass
class Body:
    """One body (2D or 3D): mesh, material, full-numbering offset and its assembled blocks."""

    name: str
    mesh: Mesh
    material: Material | Material3D
    offset: int  # first full dof of this body
    # (n_b, n_b): [[K, Gᵀ], [−G, P]] or K; released once the model's MixedVI holds it
    # (`contact_model.mixed_vi`: memory), `operator(body)` assembles it again
    A: sp.csr_matrix = None
    A_fixed: sp.csr_matrix = None  # (n_fixed_b, n_b) A's rows of the prescribed dofs (kept)
    f: np.ndarray = None  # (n_b,)
    fixed: np.ndarray = None  # (n_b,) bool
    values: np.ndarray = None  # (n_b,) prescribed values on fixed dofs

    @property
    def dim(self) -> int:
        """Space dimension d: displacement components per node."""
        return self.mesh.points.shape[1]

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
        return self.n_nodes * (self.dim + 1 if self.has_potential else self.dim)

    def u_dofs(self, nodes: np.ndarray) -> np.ndarray:
        """Full indices (len(nodes), d) of the displacement dofs of `nodes`."""
        nodes = np.asarray(nodes)
        d = self.dim
        return self.offset + d * nodes[:, None] + np.arange(d)[None, :]

    def phi_dofs(self, nodes: np.ndarray) -> np.ndarray:
        """Full indices of the potential dofs of `nodes` (piezoelectric bodies only)."""
        return self.offset + self.dim * self.n_nodes + np.asarray(nodes)

    def split(self, x_body: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Body-local full vector → displacement (N, d) and potential (N,) or None."""
        N, d = self.n_nodes, self.dim
        u = x_body[: d * N].reshape(N, d)
        phi = x_body[d * N :] if self.has_potential else None
        return u, phi


for _name in COUPLING_NAMES:
    setattr(
        Body,
        _name,
        Gone(
            f"'Body' object has no attribute {_name!r}: Interface.master is the master Body; "
            "the mortar coupling that the 3D master held (M_loc, dofs, covered, "
            "patch_defect) is Interface.coupling"
        ),
    )


Parts = BeforeValidator(one_or_many)
AXES = {2: "xy", 3: "xyz"}  # a body's displacement components by dimension


class DisplacementPart(Section):
    """A [[displacement]] part: prescribed components of u on a boundary part (m)."""

    boundary: Text
    components: Literal[tuple(COMPONENTS)] | None = Field(
        None, description="the prescribed components (default: all, xy in 2D and xyz in 3D)"
    )
    value: Vector


class TractionPart(Section):
    """A [[traction]] part: the surface force density on a boundary part (Pa)."""

    boundary: Text
    value: Vector


class ScalarPart(Section):
    """A [[potential]] (V) or [[charge]] (C/m²) part: a scalar field on a boundary part."""

    boundary: Text
    value: Expression


class BodySection(Section):
    """One [bodies.NAME] table (and signorini's [body]): geometry, material, loads, data. The
    geometry decides the body's dimension d; vectors have d entries, displacement components
    are among d axes and the material's matrices have the sizes of d."""

    material: MaterialSpec
    geometry: Geometry
    body_force: Vector | None = None
    free_charge: Expression | None = None
    displacement: Annotated[list[DisplacementPart], Parts] = []
    traction: Annotated[list[TractionPart], Parts] = []
    potential: Annotated[list[ScalarPart], Parts] = []
    charge: Annotated[list[ScalarPart], Parts] = []

    @property
    def dim(self) -> int | None:
        """The body's dimension, its geometry's (None: a mesh file that cannot be read)."""
        return self.geometry.DIM

    def boundary_refs(self) -> list[tuple[str, str]]:
        """(field path, boundary name) of every boundary this table names."""
        return [
            (part.key("boundary"), part.boundary)
            for key in ("displacement", "traction", "potential", "charge")
            for part in getattr(self, key)
        ]

    @model_validator(mode="after")
    def _consistent(self, info: ValidationInfo) -> BodySection:
        scene_dim = (info.context or {}).get("dimension")  # the scene's, if it is validated
        wrong = None if scene_dim is None else wrong_dimension(self.geometry, scene_dim)
        if wrong is not None:
            field, value, allowed = wrong
            raise refuse(["geometry", *field], value, allowed)
        names = self.geometry.BOUNDARIES
        for key in ("displacement", "traction", "potential", "charge"):
            for i, part in enumerate(getattr(self, key)):
                check_boundaries([key, i, "boundary"], [part.boundary], names)
        if self.dim is not None:
            self._sized(self.dim)
        prescribed_once("displacement", [([p.boundary], p.components) for p in self.displacement])
        prescribed_once("potential", [([p.boundary], "") for p in self.potential])
        if not self.displacement:
            raise refuse(
                ["displacement"],
                [],
                "at least one [[displacement]] part (otherwise a rigid motion is left free)",
            )
        material = self.material
        if material.piezoelectric and not self.potential:
            raise refuse(
                ["potential"],
                None,
                "at least one [[potential]] part (Γ_a, where φ is prescribed): the material "
                f"{material.label!r} is piezoelectric",
            )
        if not material.piezoelectric:
            for key in ("potential", "charge", "free_charge"):
                v = getattr(self, key)
                if v:
                    raise refuse(
                        [key],
                        v.source if isinstance(v, Expression) else [p.boundary for p in v],
                        f"not allowed: the material {material.label!r} is not piezoelectric, "
                        "so the body has no electric potential",
                    )
        return self

    def _sized(self, d: int) -> None:
        """Refuse a vector, a displacement component or a material matrix that does not fit
        the body's dimension `d`; fill in the default components (all d axes)."""
        axes, body = AXES[d], f"the body is {d}D (its geometry is)"
        vectors = [(["body_force"], self.body_force)]
        for key in ("displacement", "traction"):
            vectors += [([key, i, "value"], p.value) for i, p in enumerate(getattr(self, key))]
        for loc, v in vectors:
            if v is not None and len(v) != d:
                allowed = f"a list of {d} entries [{', '.join(axes)}]: {body}"
                raise refuse(loc, [e.source for e in v], allowed)
        for i, p in enumerate(self.displacement):
            p.components = p.components or axes
            if not set(p.components) <= set(axes):
                allowed = ", ".join(c for c in COMPONENTS if set(c) <= set(axes))
                raise refuse(
                    ["displacement", i, "components"], p.components, f"one of {allowed}: {body}"
                )
        if (wrong := self.material.wrong_size(d)) is not None:
            raise refuse(["material", wrong[0]], *wrong[1:])


def free_per_entity(
    t: BodySection, body: Body, skeleton: Skeleton
) -> tuple[np.ndarray, np.ndarray]:
    """(displacement, potential) (n_entities,) each: the free unknowns of a node inside each
    entity of `skeleton` (the body's mesh's `fem.refined_counts.Skeleton`) at any refinement
    level, the displacement components and the potential (0 or 1) that `dirichlet`'s parts
    leave free. A part holds at every level the nodes inside the entities of its closure."""
    fixed = np.zeros((skeleton.n_entities, body.dim), dtype=bool)
    for tt in t.displacement:
        on = skeleton.closure(body.mesh.boundaries[tt.boundary])  # (n_entities,)
        fixed[np.ix_(on, COMPONENTS[tt.components])] = True
    grounded = np.full(skeleton.n_entities, not body.has_potential)
    if body.has_potential:
        for tt in t.potential:
            grounded |= skeleton.closure(body.mesh.boundaries[tt.boundary])
    return body.dim - fixed.sum(axis=1), (~grounded).astype(int)


# The meshes to build the bodies on instead of meshing their geometries (body name → Mesh):
# the adaptive loop (`problems.pipeline.adaptive`) rebuilds a scene on its refined meshes
GIVEN_MESHES: ContextVar[dict[str, Mesh] | None] = ContextVar("GIVEN_MESHES", default=None)
# The level-0 meshes those were refined from (body name → Mesh): a locally refined mesh has no
# uniform level, so `separation` measures its tolerance against these meshes' sizes
LEVEL0_MESHES: ContextVar[dict[str, Mesh] | None] = ContextVar("LEVEL0_MESHES", default=None)


@contextmanager
def given_meshes(meshes: dict[str, Mesh], level0: dict[str, Mesh] | None = None) -> Iterator[None]:
    """Within it, `build_body` takes the body's mesh from `meshes` where it has one; `level0`
    (body name → Mesh): the level-0 meshes they were refined from, where the scene's geometry
    was given (`separation.separation` takes its mesh sizes from them)."""
    token = GIVEN_MESHES.set(meshes)
    token0 = LEVEL0_MESHES.set(level0)
    try:
        yield
    finally:
        LEVEL0_MESHES.reset(token0)
        GIVEN_MESHES.reset(token)


def build_body(name: str, t: BodySection, level: int, offset: int) -> Body:
    """Mesh one validated `[bodies.NAME]` table (2D or 3D) and assemble the body's blocks (the
    boundary references checked now if the geometry's parts are known only once meshed); the
    mesh is `given_meshes`'s where it has one."""
    given = (GIVEN_MESHES.get() or {}).get(name)
    mesh = t.geometry.mesh(level) if given is None else given
    if t.geometry.BOUNDARIES is None:
        check_meshed(mesh, t.boundary_refs())
    body = Body(name, mesh, t.material.material(mesh.points.shape[1]), offset)
    f = loads(t, body)
    fixed, values = dirichlet(t, body)
    # under an engine's row partition A is assembled later, by owned rows (`owned.assemble`)
    A = operator(body) if row_partition() is None else None
    body.A, body.f, body.fixed, body.values = A, f, fixed, values
    return body


def gram(body: Body) -> sp.csr_matrix:
    """(n_b, n_b) the H1 Gram matrix of the body's fields (the norm of `vi_core.constants`),
    assembled from its mesh: mass + stiffness per displacement component, and the same for the
    potential of a piezoelectric material."""
    d = body.dim
    H1 = (assembly.mass_matrix(body.mesh) + assembly.stiffness_matrix(body.mesh)).tocsr()
    blocks = [sp.kron(H1, sp.identity(d)).tocsr()]  # node-major: dof d·i + k ↔ (i, k)
    if body.material.piezoelectric:
        blocks.append(H1)
    return sp.block_diag(blocks, format="csr")


def operator(body: Body, rows: np.ndarray | None = None) -> sp.csr_matrix:
    """(n_b, n_b) the body's operator A assembled from its mesh and material: [[K, Gᵀ], [−G, P]]
    with a piezoelectric material, else K. rows (n_b,) bool: only those rows (the others
    empty), bit for bit the whole operator's (`fem.assembly`'s owned-rows assembly)."""
    m = body.material
    if m.piezoelectric:
        return assembly.piezo_matrix(body.mesh, m.C, m.e, m.kappa, rows=rows)
    return assembly.elasticity_matrix(body.mesh, m.C, rows=rows).tocsr()


def loads(t: BodySection, body: Body) -> np.ndarray:
    """(n_b,) the body's load vector (body-local full numbering): body force and tractions on
    the displacement rows, free charge and surface charge on the potential rows (piezoelectric
    bodies), each expression at the current load parameter."""
    mesh, N, d = body.mesh, body.n_nodes, body.dim
    f = np.zeros(body.size)
    if t.body_force is not None:
        f[: d * N] += assembly.volume_load(mesh, vector(t.body_force), d)
    for tt in t.traction:
        f[: d * N] += assembly.boundary_load(mesh, tt.boundary, vector(tt.value), d)
    if body.has_potential:
        fphi = np.zeros(N)
        if t.free_charge is not None:
            fphi += assembly.volume_load(mesh, t.free_charge, 1)
        for tt in t.charge:
            fphi -= assembly.boundary_load(mesh, tt.boundary, tt.value, 1)
        f[d * N :] = fphi
    return f


def dirichlet(t: BodySection, body: Body) -> tuple[np.ndarray, np.ndarray]:
    """(fixed (n_b,) bool, values (n_b,)) of the body's prescribed displacement components and
    potentials (body-local full numbering; values 0 where free)."""
    mesh, N, d = body.mesh, body.n_nodes, body.dim
    fixed = np.zeros(body.size, dtype=bool)
    values = np.zeros(body.size)
    for tt in t.displacement:
        nodes = mesh.boundary_nodes(tt.boundary)
        val = evaluate(tt.value, *coordinates(mesh, nodes))  # (k, d)
        for c in COMPONENTS[tt.components]:
            fixed[d * nodes + c] = True
            values[d * nodes + c] = val[:, c]
    if body.has_potential:
        for tt in t.potential:
            nodes = mesh.boundary_nodes(tt.boundary)
            fixed[d * N + nodes] = True
            values[d * N + nodes] = tt.value(*coordinates(mesh, nodes))
    return fixed, values


# The rotations of the rigid-body modes by dimension: (i, j) turns x_i into x_j, the mode
# (−x_j, x_i) on the components (i, j) (2D: about z; 3D: about x, y, z)
ROTATIONS = {2: ((0, 1),), 3: ((1, 2), (2, 0), (0, 1))}


def field_data(bodies: list[Body], free: np.ndarray, n_full: int) -> dict:
    """`MixedVI` keywords fields and near_null, for `vi_core.krylov`'s per-field multigrid:
    displacement and potential masks over the unknowns `free` (full indices), and the
    displacement block's rigid-body modes (n_disp, d + len(ROTATIONS[d])): the d translations,
    then the rotations (the potential block's near-null space is the constant, the default)."""
    dim = bodies[0].dim
    comp = np.full(n_full, -1)  # displacement component of each full dof, −1 = potential
    xyz = np.zeros((n_full, dim))  # (n_full, d) node coordinates of each displacement dof
    for b in bodies:
        d = b.u_dofs(np.arange(b.n_nodes))  # (N, d)
        comp[d] = np.arange(dim)[None, :]
        for k in range(dim):
            xyz[d[:, k]] = b.mesh.points
    c, p = comp[free], xyz[free]  # (n,), (n, d)
    disp = c >= 0
    modes = np.zeros((free.size, dim + len(ROTATIONS[dim])))  # (n, modes)
    for k in range(dim):
        modes[c == k, k] = 1.0
    for r, (i, j) in enumerate(ROTATIONS[dim]):
        modes[c == i, dim + r] = -p[c == i, j]
        modes[c == j, dim + r] = p[c == j, i]
    fields = {"displacement": disp}
    if (~disp).any():
        fields["potential"] = ~disp
    return {"fields": fields, "near_null": {"displacement": modes[disp]}}
