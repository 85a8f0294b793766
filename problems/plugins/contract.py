"""The plug-in contract: what `mixvi` expects from a problem module and from the model it builds.

Contract version CONTRACT = 2. A plug-in is one module (or any object) with

    NAME: str                                  the name scenes use: [scene] plugin = NAME
    DESCRIPTION: str                           one line for listings
    SCENE_MODEL: type[SceneModel]              its scene model (pydantic): every key, type,
                                               range and cross-reference of its scenes
    build(scene, level) -> Model               validated scene → assembled mixed VI
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
(a float) are also printed. Before anything is built the scene is validated by SCENE_MODEL
(`mixvi validate`, `mixvi schema` shows the JSON Schema); `build` reads the scene only through
`scene.validated(SCENE_MODEL)` (cached) and raises `SceneError(field, value, allowed)` for
what only the built mesh can tell (an expression's value, a mesh too large), naming the field
with the sections' `key(name)` and the expressions' own `path`.

Optionally a plug-in also provides `fields(model, sol) -> dict[str, np.ndarray]` (nodal fields
by name) and `contact_state(model, sol) -> dict` for the Python API (`problems.solve_scene`).

The helpers below are shared by the built-in scalar plug-ins and are free to use in your own.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Protocol, runtime_checkable

import numpy as np
from pydantic import BeforeValidator, Field

from fem.mesh import Mesh
from problems.scene import Scene, SceneModel, Section
from problems.scene.fields import Expression, Text, Vector, evaluate
from problems.scene.model import refuse
from vi_core import MixedVI, Solution

CONTRACT = 2  # the version of this contract (docs/plugins.md: what changed from 1 to 2)


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
    """A problem module: `registry` accepts any object with these five attributes."""

    NAME: str
    DESCRIPTION: str
    SCENE_MODEL: type[SceneModel]

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
    sm = getattr(obj, "SCENE_MODEL", None)
    if not (isinstance(sm, type) and issubclass(sm, SceneModel)):
        missing.append("SCENE_MODEL (a subclass of problems.scene.SceneModel; contract 2)")
    return missing


# ------------------------------------------------------------------ helpers for plug-ins
Boundaries = Annotated[
    list[Text],
    BeforeValidator(
        lambda v: [v] if isinstance(v, str) else v, json_schema_input_type=str | list[str]
    ),
    Field(min_length=1),
]


def check_boundaries(field: list, names: list[str], available) -> None:
    """Refuse (a pydantic error at `field`) any of `names` not among `available` (a geometry's
    BOUNDARIES; None: known only once meshed, checked then)."""
    if available is None:
        return
    for n in names:
        if n not in available:
            raise refuse(field, n, f"a boundary of this geometry: {', '.join(available)}")


class ScalarExact(Section):
    """The optional [exact] table of a scalar plug-in: u and grad = [∂x u, ∂y u]."""

    source: Text = ""  # where the exact solution comes from (documentation only)
    u: Expression
    grad: Vector

    def compiled(self) -> tuple[Callable, Grad]:
        """(u(x, y), grad(x, y) → x.shape + (2,))."""
        g = self.grad
        return self.u, lambda x, y: evaluate(g, x, y)


class DirichletPart(Section):
    """One [[dirichlet]] table of a scalar plug-in: boundary part(s) and the value there."""

    boundary: Boundaries
    value: Expression


def dirichlet(parts: list[DirichletPart], mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Scalar Dirichlet data: fixed (n_nodes,) bool and values (n_nodes,) (0 where free)."""
    fixed = np.zeros(mesh.n_nodes, dtype=bool)
    values = np.zeros(mesh.n_nodes)
    for t in parts:
        nodes = np.unique(np.concatenate([mesh.boundaries[p] for p in t.boundary]))  # (k,)
        fixed[nodes] = True
        values[nodes] = t.value(mesh.points[nodes, 0], mesh.points[nodes, 1])
    return fixed, values


Grad = Callable[[np.ndarray, np.ndarray], np.ndarray]


def complementarity_defect(lam: np.ndarray, slack: np.ndarray, support: float) -> float:
    """Relative defect of λᵀ(Bu − gap) = σ (σ = Σ g_i D_i |(Bu)_i| for Tresca rows, 0 else).

    slack = Bu − gap. Relative to max(|σ|, ‖λ‖‖slack‖): the Cauchy–Schwarz bound of the left
    side, so a pure complementarity (σ = 0) is measured as the cosine between λ and the slack.
    """
    lhs = float(lam @ slack)
    scale = max(abs(support), float(np.linalg.norm(lam) * np.linalg.norm(slack)), 1e-300)
    return abs(lhs - support) / scale


def triangles(mesh: Mesh) -> np.ndarray:
    """(n_tri, 3) triangles of `mesh` for plotting (each quad split along a diagonal)."""
    if mesh.cell_type == "triangle":
        return mesh.cells
    c = mesh.cells  # (n_cells, 4)
    return np.concatenate([c[:, [0, 1, 2]], c[:, [0, 2, 3]]])
