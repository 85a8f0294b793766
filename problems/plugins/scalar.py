"""What the scalar P1 plug-ins (antiplane, obstacle) share: the checks of their boundary
parts, the Dirichlet-reduced −μΔ, the model's common part (one mesh, the free nodes, the
Dirichlet values, the [exact] fields) and the study hooks built on it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from fem import assembly
from fem.dirichlet import expand, reduce_dirichlet
from fem.mesh import Mesh
from problems.scene import Scene, SceneModel
from vi_core import MixedVI, Solution

from .contract import check_boundaries, check_meshed, prescribed_once
from .transfer import nodal_reference_errors


def check_parts(spec: SceneModel, keys: Sequence[str]) -> None:
    """Scene check: the geometry has the boundary parts of the list tables `keys`, and no
    [[dirichlet]] part is given twice."""
    names = spec.domain.geometry.BOUNDARIES
    for key in keys:
        for i, d in enumerate(getattr(spec, key)):
            check_boundaries([key, i, "boundary"], d.boundary, names)
    prescribed_once("dirichlet", [(d.boundary, "") for d in spec.dirichlet])


def meshed(spec: SceneModel, level: int, keys: Sequence[str], extra: Sequence = ()) -> Mesh:
    """The mesh at `level`; from a file, checked to have the parts of the list tables `keys` and
    each (field path, boundary name) of `extra`."""
    mesh = spec.domain.geometry.mesh(level)
    if spec.domain.geometry.BOUNDARIES is None:
        refs = [(d.key("boundary"), b) for k in keys for d in getattr(spec, k) for b in d.boundary]
        check_meshed(mesh, [*refs, *extra])
    return mesh


def reduced(
    mesh: Mesh, F: np.ndarray, fixed: np.ndarray, values: np.ndarray, mu: float = 1.0
) -> tuple:
    """−μΔu = F, u = values on `fixed` (n_nodes,) reduced (fem.dirichlet): free, A = μK_ff,
    f = F_f − μK_fD u_D and X = (M + K)_ff, the H¹ Gram matrix (K stiffness, M mass)."""
    K = assembly.stiffness_matrix(mesh)
    A, f, free = reduce_dirichlet(mu * K, F, fixed, values)
    X = (assembly.mass_matrix(mesh) + K)[free][:, free]
    return free, A, f, X


@dataclass
class ScalarModel:
    """A scalar nodal unknown on one mesh, reduced by its Dirichlet nodes. A plug-in's model
    adds its own fields after these; `exact`, `options` and `warnings` are keyword-only."""

    scene: Scene
    level: int
    mesh: Mesh
    vi: MixedVI
    free: np.ndarray  # (n_free,) node ids of the unknowns
    values: np.ndarray  # (n_nodes,) Dirichlet values (fixed nodes)
    exact: tuple | None = field(default=None, kw_only=True)  # (u, grad) of the [exact] table
    options: dict = field(default_factory=dict, kw_only=True)
    warnings: list[str] = field(default_factory=list, kw_only=True)

    @property
    def dofs(self) -> dict[str, int]:
        return {"displacement": int(self.free.size), "multiplier": self.vi.m}

    def full(self, u: np.ndarray) -> np.ndarray:
        """(n_nodes,) nodal values including the Dirichlet data."""
        return expand(u, self.free, self.values)

    def errors(self, sol: Solution) -> dict[str, float]:
        """|u − u_h|_H1 and ‖u − u_h‖_L2 against the scene's [exact] solution, and h."""
        if self.exact is None:
            raise ValueError(f"scene {self.scene.name!r} has no [exact] table")
        u, grad = self.exact
        x = self.full(sol.u)
        return {
            "h1": assembly.h1_seminorm_error(self.mesh, x, grad, 1),
            "l2": assembly.l2_error(self.mesh, x, u, 1),
            "h": self.mesh.h,
        }


def mesh_size(model: ScalarModel) -> float:
    """h of the built level (contract: `mesh_size`) of a plug-in with one `model.mesh`."""
    return model.mesh.h


def exact_errors(model: ScalarModel, sol: Solution) -> dict[str, float] | None:
    """H¹ and L² errors (keys "h1", "l2") against the scene's [exact] table (contract:
    `exact_errors`); None without one."""
    if model.exact is None:
        return None
    err = model.errors(sol)
    return {k: err[k] for k in ("h1", "l2")}


def reference_errors(
    model: ScalarModel, sol: Solution, ref: ScalarModel, ref_sol: Solution
) -> dict:
    """‖u_h − u_ref‖ in H¹ and L² against the finer level `ref` (contract: `reference_errors`)
    for a plug-in whose model maps its unknowns to nodal values with `model.full`."""
    return nodal_reference_errors(model.mesh, model.full(sol.u), ref.mesh, ref.full(ref_sol.u))
