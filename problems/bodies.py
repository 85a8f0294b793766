"""Bodies of a contact scene: geometry → mesh, material, loads, Dirichlet data, assembly.

A body owns its displacement unknowns and, only if its material is piezoelectric, its
potential unknowns. Global (full) numbering: body after body, displacement (2·N, node-major)
then potential (N).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from fem import assembly
from fem.boundary import trace
from fem.mesh import Mesh
from fem.meshing import rectangle

from .errors import SceneError
from .materials import Material, material_from_scene
from .scene import Table

GEOMETRIES = ("rectangle", "half_disc", "cradle")
COMPONENTS = {"x": (0,), "y": (1,), "xy": (0, 1)}
MAX_CELLS = 4_000_000  # cells of one body at the requested level (≈ 12M piezo unknowns)


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


def make_mesh(t: Table, level: int) -> Mesh:
    """The mesh of a `geometry` table at refinement `level`.

    SceneError (naming the geometry key) for a mesh too large to build (more than MAX_CELLS
    cells) or one the mesher refuses: inverted or degenerate cells, zero-length edges.
    """
    kind = t.string("kind", choices=GEOMETRIES)
    scale = 2**level
    if kind == "rectangle":
        x0, x1 = t.pair("x")
        y0, y1 = t.pair("y")
        if not x0 < x1:
            raise SceneError(t.key("x"), [x0, x1], "an interval [x0, x1] with x0 < x1")
        if not y0 < y1:
            raise SceneError(t.key("y"), [y0, y1], "an interval [y0, y1] with y0 < y1")
        nx, ny = t.pair("cells", kind=int)
        if nx < 1 or ny < 1:
            raise SceneError(t.key("cells"), [nx, ny], "two positive integers [nx, ny]")
        element = t.string("element", "quad", choices=("quad", "triangle"))
        t.finish()
        _check_size(t, "cells", [nx, ny], nx * ny * scale**2)
        return _meshed(t, rectangle, (x0, x1), (y0, y1), (nx * scale, ny * scale), element)
    from fem import shapes

    center = t.pair("center", [0.0, 1.5])
    radius = t.number("radius", 1.0, lo=0.0, lo_open=True)
    angle = t.number("angle", np.pi / 2, lo=0.0, hi=np.pi, lo_open=True)
    if angle >= np.pi:
        raise SceneError(t.key("angle"), angle, "an opening angle in (0, π)")
    n_contact = t.integer("n_contact", 8 if kind == "half_disc" else 12, lo=1)
    if kind == "half_disc":
        t.finish()
        # shapes.half_disc: n_f cells along each free arc, n_r along the spokes (level 0)
        h = angle / n_contact
        n_f = max(1, round((np.pi / 2 - angle / 2) / h))
        n_r = max(1, round(0.5 / h))
        cells = (n_contact + 2 * n_f) * n_r + n_contact * n_f
        _check_size(t, "n_contact", n_contact, cells * scale**2)
        return _meshed(t, shapes.half_disc, center, radius, angle, n_contact, level)
    p2 = t.pair("p2", [-1.0, 0.0])
    p3 = t.pair("p3", [1.0, 0.0])
    t.finish()
    Cl, Cr = shapes.contact_ends(center, radius, angle)
    height = 0.5 * (np.hypot(*(Cl - p2)) + np.hypot(*(Cr - p3)))
    n_y = max(1, round(height / (radius * angle / n_contact)))
    _check_size(t, "n_contact", n_contact, n_contact * n_y * scale**2)
    return _meshed(t, shapes.cradle, p2, p3, center, radius, angle, n_contact, level)


def _check_size(t: Table, key: str, value, cells: float) -> None:
    if cells > MAX_CELLS:
        raise SceneError(
            t.key(key),
            value,
            f"a mesh of at most {MAX_CELLS:,} cells per body at the requested level "
            f"(this geometry would have about {cells:.3g})",
        )


def _meshed(t: Table, mesher, *args) -> Mesh:
    """Call a mesher and trace every boundary part; a ValueError (inverted or degenerate
    cells, zero-length boundary segments) becomes a SceneError naming the geometry."""
    with np.errstate(all="ignore"):
        try:
            mesh = mesher(*args)
            for part in mesh.boundaries:
                trace(mesh, part)
            return mesh
        except ValueError as err:
            raise SceneError(
                t.path, t.data, f"a geometry that meshes into valid cells ({err})"
            ) from None


def _boundary(t: Table, mesh: Mesh, body: str) -> str:
    name = t.string("boundary")
    if name not in mesh.boundaries:
        raise SceneError(
            t.key("boundary"),
            name,
            f"a boundary of body {body!r}: {', '.join(sorted(mesh.boundaries))}",
        )
    return name


def build_body(name: str, t: Table, level: int, offset: int) -> Body:
    """Read one `[bodies.NAME]` table and assemble the body's blocks."""
    mesh = make_mesh(t.table("geometry"), level)
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
