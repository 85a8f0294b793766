"""Bodies of a contact scene: geometry → mesh, material, loads, Dirichlet data, assembly.

A body owns its displacement unknowns and, only if its material is piezoelectric, its
potential unknowns. Global (full) numbering: body after body, displacement (2·N, node-major)
then potential (N).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from fem import assembly
from fem.mesh import Mesh
from problems.errors import SceneError
from problems.scene import Table
from problems.scene.geometry import make_mesh
from problems.scene.materials import Material, material_from_scene

COMPONENTS = {"x": (0,), "y": (1,), "xy": (0, 1)}


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


def _boundary(t: Table, mesh: Mesh, body: str) -> str:
    name = t.string("boundary")
    if name not in mesh.boundaries:
        raise SceneError(
            t.key("boundary"),
            name,
            f"a boundary of body {body!r}: {', '.join(sorted(mesh.boundaries))}",
        )
    return name


def build_body(name: str, t: Table, level: int, offset: int, scene_dir: Path | None = None) -> Body:
    """Read one `[bodies.NAME]` table and assemble the body's blocks (`scene_dir`: the
    folder mesh files are relative to)."""
    mesh = make_mesh(t.table("geometry"), level, scene_dir)
    material = material_from_scene(t.key("material"), t.raw("material", allowed="a material"))
    body = Body(name, mesh, material, offset)
    N = mesh.n_nodes
    n_b = body.size
    K = assembly.elasticity_matrix(mesh, material.C)
    f = np.zeros(n_b)
    fixed = np.zeros(n_b, dtype=bool)
    values = np.zeros(n_b)
    if t.has("body_force"):
        f[: 2 * N] += assembly.volume_load(mesh, t.field("body_force", 2), 2)
    for tt in t.tables("traction"):
        part = _boundary(tt, mesh, name)
        f[: 2 * N] += assembly.boundary_load(mesh, part, tt.field("value", 2), 2)
        tt.finish()
    for tt in t.tables("displacement"):
        part = _boundary(tt, mesh, name)
        comps = COMPONENTS[tt.string("components", "xy", choices=COMPONENTS)]
        nodes = mesh.boundary_nodes(part)
        val = tt.field("value", 2)(mesh.points[nodes, 0], mesh.points[nodes, 1])  # (k, 2)
        for c in comps:
            fixed[2 * nodes + c] = True
            values[2 * nodes + c] = val[:, c]
        tt.finish()
    if not fixed[: 2 * N].any():
        raise SceneError(
            t.key("displacement"),
            None,
            f"body {name!r} needs at least one [[bodies.{name}.displacement]] part "
            "(otherwise a rigid motion is left free)",
        )
    Mu = assembly.mass_matrix(mesh)
    Su = assembly.stiffness_matrix(mesh)
    H1 = (Mu + Su).tocsr()
    X_blocks = [sp.kron(H1, sp.identity(2)).tocsr()]  # node-major: dof 2·i + k ↔ (i, k)
    if material.piezoelectric:
        G = assembly.coupling_matrix(mesh, material.e)
        P = assembly.permittivity_matrix(mesh, material.kappa)
        A = sp.bmat([[K, G.T], [-G, P]], format="csr")
        fphi = np.zeros(N)
        if t.has("free_charge"):
            fphi += assembly.volume_load(mesh, t.field("free_charge", 1), 1)
        for tt in t.tables("charge"):
            part = _boundary(tt, mesh, name)
            fphi -= assembly.boundary_load(mesh, part, tt.field("value", 1), 1)
            tt.finish()
        f[2 * N :] = fphi
        for tt in t.tables("potential"):
            part = _boundary(tt, mesh, name)
            nodes = mesh.boundary_nodes(part)
            fixed[2 * N + nodes] = True
            values[2 * N + nodes] = tt.field("value", 1)(
                mesh.points[nodes, 0], mesh.points[nodes, 1]
            )
            tt.finish()
        if not fixed[2 * N :].any():
            raise SceneError(
                t.key("potential"),
                None,
                f"body {name!r} is piezoelectric and needs at least one "
                f"[[bodies.{name}.potential]] part (Γ_a, where φ is prescribed)",
            )
        X_blocks.append(H1)
    else:
        A = K.tocsr()
        for key in ("potential", "charge", "free_charge"):
            if t.has(key):
                raise SceneError(
                    t.key(key),
                    t.raw(key),
                    f"not allowed: body {name!r} is not piezoelectric (material "
                    f"{material.name!r}), so it has no electric potential",
                )
    t.finish()
    body.A, body.f, body.fixed, body.values = A, f, fixed, values
    body.X = sp.block_diag(X_blocks, format="csr")
    return body
