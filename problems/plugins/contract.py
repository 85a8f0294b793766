"""The plug-in contract: what `mixvi` expects from a problem module and from the model it builds.

A plug-in is one module (or any object) with

    NAME: str                                  the name scenes use: [scene] plugin = NAME
    DESCRIPTION: str                           one line for listings
    build(scene, level) -> Model               scene (TOML) → assembled mixed VI
    postprocess(model, sol, outdir) -> dict    solution → files in outdir + summary entries

and the `Model` it returns carries

    vi: MixedVI                                the discrete problem A u + Bᵀλ = f, λ ∈ Λ, ...
    level: int                                 the refinement level actually built
    dofs: dict[str, int]                       unknowns per field (printed and summarised)
    options: dict                              e.g. {"method": "ssn", "tol": 1e-10} from the scene
    warnings: list[str]                        anything the user should read

and optionally
    dimension: int                             the geometry's dimension (default 2): each
                                               level multiplies the unknowns by 2**dimension
                                               in the memory estimate before a level is built
    errors(sol) -> dict[str, float]            errors against a known exact solution
                                               (e.g. {"h1": ..., "l2": ...}, plus "h")
    complementarity(sol) -> float              relative defect of a Lemma-4.2-type identity
                                               λᵀ(Bu − gap) = (support function term), 0 exactly

`mixvi solve` calls exactly: build → `vi_core.solve(model.vi, method=options.get("method",
"ssn"), tol=options.get("tol", 1e-10))` → postprocess, and merges the returned dict into
summary.json; the keys "contact" ({"nodes", "stick", "slip"}, optionally
"mortar_patch_defect": above 1e-8 `mixvi solve` exits 1 unless --allow-defect) and "lemma_4_2"
(a float) are also printed. `build` raises `SceneError` for bad input (read the scene through
`Scene.root()`, whose `Table` methods name the key and value, and call `Table.finish()` to
refuse unknown keys).

The helpers below are shared by the built-in scalar plug-ins and are free to use in your own.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from fem.mesh import Mesh
from problems.errors import SceneError
from problems.scene import Scene, Table
from vi_core import MixedVI, Solution


@runtime_checkable
class Model(Protocol):
    """What `build` returns (a dataclass in the built-in plug-ins)."""

    vi: MixedVI
    level: int
    options: dict
    warnings: list[str]

    @property
    def dofs(self) -> dict[str, int]:
        """Number of unknowns per field, e.g. {"displacement": 130, "multiplier": 17}."""


@runtime_checkable
class Plugin(Protocol):
    """A problem module: `registry` accepts any object with these four attributes."""

    NAME: str
    DESCRIPTION: str

    def build(self, scene: Scene, level: int | None) -> Model:
        """Scene → Model; `level` None means the scene's default level."""

    def postprocess(self, model: Model, sol: Solution, outdir: Path) -> dict:
        """Write result files into `outdir` and return summary entries (JSON-able)."""


def conforms(obj: Any) -> list[str]:
    """What `obj` lacks to be a plug-in (empty list: it conforms)."""
    missing = []
    for attr, kind in (("NAME", str), ("DESCRIPTION", str)):
        if not isinstance(getattr(obj, attr, None), kind):
            missing.append(f"{attr} (a string)")
    for attr in ("build", "postprocess"):
        if not callable(getattr(obj, attr, None)):
            missing.append(f"{attr}() (a function)")
    return missing


# ------------------------------------------------------------------ helpers for plug-ins
def read_head(root: Table, name: str, default_level: int = 1) -> int:
    """Check the [scene] table of a plug-in `name` and return its default level."""
    head = root.table("scene")
    head.string("title", "")
    head.string("description", "")
    head.string("plugin", choices=(name,))
    level = head.integer("level", default_level, lo=0, hi=12)
    head.finish()
    return level


def read_solver(root: Table) -> dict:
    """The optional [solver] table: {"method": ..., "tol": ...} (only the keys given)."""
    t = root.table("solver", required=False)
    options: dict = {}
    if t is not None:
        if t.has("method"):
            options["method"] = t.string("method", choices=("auto", "ssn", "conic", "homotopy"))
        if t.has("tol"):
            options["tol"] = t.number("tol", lo=0.0, lo_open=True)
        t.finish()
    return options


Grad = Callable[[np.ndarray, np.ndarray], np.ndarray]


def read_exact(root: Table, ncomp: int = 1) -> tuple[Callable, Grad] | None:
    """The optional [exact] table: u = field, grad = [∂x u, ∂y u] (scalar: ncomp = 1).

    Returns (u(x, y), grad(x, y) → x.shape + (2,)) or None if the table is absent.
    """
    t = root.table("exact", required=False)
    if t is None:
        return None
    t.string("source", "")  # where the exact solution comes from (documentation only)
    u = t.field("u", ncomp)
    g = t.field("grad", 2)
    t.finish()
    return u, g


def complementarity_defect(lam: np.ndarray, slack: np.ndarray, support: float) -> float:
    """Relative defect of λᵀ(Bu − gap) = σ (σ = Σ g_i D_i |(Bu)_i| for Tresca rows, 0 else).

    slack = Bu − gap. Relative to max(|σ|, ‖λ‖‖slack‖): the Cauchy–Schwarz bound of the left
    side, so a pure complementarity (σ = 0) is measured as the cosine between λ and the slack.
    """
    lhs = float(lam @ slack)
    scale = max(abs(support), float(np.linalg.norm(lam) * np.linalg.norm(slack)), 1e-300)
    return abs(lhs - support) / scale


def read_boundaries(t: Table, name: str, available: dict) -> list[str]:
    """A boundary part name or a list of them, each checked against `available`."""
    v = t.raw(name, allowed="a boundary name or a list of them")
    parts = [v] if isinstance(v, str) else v
    known = ", ".join(sorted(available))
    if not isinstance(parts, list) or not parts or not all(isinstance(p, str) for p in parts):
        raise SceneError(t.key(name), v, f"a boundary name or a list of them: {known}")
    for p in parts:
        if p not in available:
            raise SceneError(t.key(name), p, f"a boundary of this mesh: {known}")
    return parts


def triangles(mesh: Mesh) -> np.ndarray:
    """(n_tri, 3) triangles of `mesh` for plotting (each quad split along a diagonal)."""
    if mesh.cell_type == "triangle":
        return mesh.cells
    c = mesh.cells  # (n_cells, 4)
    return np.concatenate([c[:, [0, 1, 2]], c[:, [0, 2, 3]]])


def read_dirichlet(
    root: Table, mesh: Mesh, name: str = "dirichlet"
) -> tuple[np.ndarray, np.ndarray]:
    """Scalar Dirichlet data from [[name]] tables (boundary = part(s), value = field).

    Returns fixed (n_nodes,) bool and values (n_nodes,) (zero where not fixed); SceneError if
    there is no such table (the scalar problem would have no unique solution).
    """
    fixed = np.zeros(mesh.n_nodes, dtype=bool)
    values = np.zeros(mesh.n_nodes)
    for t in root.tables(name):
        parts = read_boundaries(t, "boundary", mesh.boundaries)
        nodes = np.unique(np.concatenate([mesh.boundaries[p] for p in parts]))  # (k,)
        fixed[nodes] = True
        values[nodes] = t.field("value", 1)(mesh.points[nodes, 0], mesh.points[nodes, 1])
        t.finish()
    if not fixed.any():
        raise SceneError(name, None, f"at least one [[{name}]] table (boundary = ..., value = ...)")
    return fixed, values
