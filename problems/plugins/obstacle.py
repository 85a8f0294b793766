"""Plug-in: the obstacle problem for a membrane, −Δu = f in Ω, u = u_D on ∂Ω, u ≥ ψ.

P1/Q1 elements; one multiplier per free node, the nodal contact force λ_i ≥ 0:

    K u + Bᵀλ = F,   B = −I (free nodes),   gap = −ψ,   Λ = NonNegative(n_free),

so vi_core's (Bu − gap) ∈ N_Λ(λ) reads ψ − u ≤ 0, λ ≥ 0, λᵢ(ψᵢ − uᵢ) = 0 and K u = F + λ:
the obstacle pushes the membrane up where they touch. A is the (symmetric) stiffness matrix.

Scene tables: [domain] geometry (as for bodies: rectangle, half_disc, cradle), load f (field),
obstacle ψ (field); [[dirichlet]] boundary (name or list), value (field); optional [exact]
u, grad, source; optional [solver] method, tol.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import scipy.sparse as sp
from pydantic import BeforeValidator, Field, model_validator

from fem import assembly
from problems.output import plots
from problems.scene import Scene, SceneModel, Section
from problems.scene.fields import Expression
from problems.scene.geometry import PlaneGeometry
from problems.scene.model import head, one_or_many
from vi_core import MixedVI, NonNegative, Solution
from vi_core import states as node_states

from . import scalar
from .contract import (
    DirichletPart,
    ExtremeRow,
    ScalarExact,
    Sweep,
    complementarity_defect,
    dirichlet,
    expect,
    triangles,
)
from .scalar import ScalarModel

NAME = "obstacle"
DESCRIPTION = "membrane above an obstacle: −Δu = f, u ≥ ψ (nodal contact forces λ ≥ 0)"
Head = head(NAME, 2)


@dataclass
class Model(ScalarModel):
    """The assembled obstacle problem."""

    psi: np.ndarray  # (n_nodes,) nodal obstacle

    def complementarity(self, sol: Solution) -> float:
        """Relative defect of λᵀ(ψ − u) = 0 (exact for any solution of the VI)."""
        return complementarity_defect(sol.lam, self.vi.B @ sol.u - self.vi.gap, 0.0)


class Domain(Section):
    """[domain]: geometry, load f (a field), obstacle ψ (a field)."""

    geometry: PlaneGeometry
    load: Expression = Expression(0.0)
    obstacle: Expression


class ObstacleScene(SceneModel):
    """An obstacle scene: [domain], [[dirichlet]] (at least one), optional [exact]."""

    scene: Head
    domain: Domain
    dirichlet: Annotated[list[DirichletPart], BeforeValidator(one_or_many), Field(min_length=1)]
    exact: ScalarExact | None = None

    @model_validator(mode="after")
    def _references(self) -> ObstacleScene:
        scalar.check_parts(self, ("dirichlet",))
        return self


SCENE_MODEL = ObstacleScene


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model: mesh, stiffness, load, Dirichlet reduction, one constraint per free node."""
    spec = scene.validated(SCENE_MODEL)
    level = spec.scene.level if level is None else level
    mesh = scalar.meshed(spec, level, ("dirichlet",))
    f_fun, psi_fun = spec.domain.load, spec.domain.obstacle
    fixed, values = dirichlet(spec.dirichlet, mesh)
    exact = None if spec.exact is None else spec.exact.compiled()
    options = spec.options()

    x, y = mesh.points.T  # (n_nodes,) each
    psi = psi_fun(x, y)  # (n_nodes,)
    F = assembly.volume_load(mesh, f_fun, 1)  # (n_nodes,)
    free, A, f, X = scalar.reduced(mesh, F, fixed, values)
    n = free.size
    vi = MixedVI(
        A=A,
        B=-sp.identity(n, format="csr"),
        f=f,
        Lambda=NonNegative(n),
        gap=-psi[free],
        X=X,
        info={"scene": scene.name, "level": level},
    )
    warnings = []
    below = np.flatnonzero(fixed & (values < psi - 1e-12 * max(np.abs(psi).max(), 1.0)))
    if below.size:
        warnings.append(
            f"Dirichlet data lie below the obstacle at {below.size} boundary node(s), e.g. "
            f"{mesh.points[below[0]].tolist()}: u ≥ ψ cannot hold there"
        )
    return Model(
        scene, level, mesh, vi, free, values, psi, exact=exact, options=options, warnings=warnings
    )


def fields(model: Model, sol: Solution) -> dict[str, np.ndarray]:
    """Nodal fields: "u", "obstacle" and "contact_force" (n_nodes,) each."""
    lam = np.zeros(model.mesh.n_nodes)
    lam[model.free] = sol.lam
    return {"u": model.full(sol.u), "obstacle": model.psi, "contact_force": lam}


def postprocess(model: Model, sol: Solution, outdir: Path) -> dict:
    """obstacle.vtu (u, ψ, λ, contact) and obstacle.png (u and contact set; mid-line profile)."""
    from fem.io import write_vtu

    u = model.full(sol.u)  # (n_nodes,)
    lam = np.zeros_like(u)
    lam[model.free] = sol.lam
    labels = _states(model, sol)  # (n_free,)
    on = labels == "touch"
    contact = np.zeros_like(u)
    contact[model.free[on]] = 1.0
    write_vtu(
        outdir / "obstacle.vtu",
        model.mesh,
        {"u": u, "obstacle": model.psi, "contact_force": lam, "contact": contact},
    )
    _plot(model, u, contact > 0, outdir / "obstacle.png")
    summary = {
        "obstacle": {
            "nodes": int(model.free.size),
            "contact": int(on.sum()),
            "ambiguous": int(np.sum(labels == "ambiguous")),
        },
        "complementarity": model.complementarity(sol),
        "files": ["obstacle.png", "obstacle.vtu"],
        "warnings": node_states.warnings(labels),
    }
    if model.exact is not None:
        summary["errors"] = model.errors(sol)
    return summary


def _mid_line(P: np.ndarray) -> tuple[float, np.ndarray]:
    """The node row nearest the median height of the points P (n_nodes, 2): (its y, (k,) its
    nodes from left to right)."""
    ymid = P[np.argmin(np.abs(P[:, 1] - np.median(P[:, 1]))), 1]
    row = np.flatnonzero(np.isclose(P[:, 1], ymid))
    return ymid, row[np.argsort(P[row, 0])]


def _plot(model: Model, u: np.ndarray, touch: np.ndarray, path: Path) -> None:
    plt = plots.pyplot()
    P = model.mesh.points  # (n_nodes, 2)
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(11, 4.5))
    tpc = a0.tripcolor(P[:, 0], P[:, 1], triangles(model.mesh.cells), u, shading="gouraud")
    a0.plot(P[touch, 0], P[touch, 1], "k.", ms=2, label="contact (λ > 0)")
    a0.set_aspect("equal")
    a0.legend(loc="upper right", fontsize=8)
    fig.colorbar(tpc, ax=a0, label="u")
    ymid, row = _mid_line(P)
    a1.plot(P[row, 0], u[row], "o-", ms=3, label="$u_h$")
    a1.plot(P[row, 0], model.psi[row], "k--", lw=1, label=r"obstacle $\psi$")
    if model.exact is not None:
        a1.plot(P[row, 0], model.exact[0](P[row, 0], P[row, 1]), "-", lw=1, label="exact")
    a1.set_xlabel(f"x (y = {ymid:.3g})")
    a1.legend(loc="best", fontsize=8)
    fig.suptitle(f"{model.scene.name}, level {model.level}: {int(touch.sum())} nodes in contact")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------ contract v2 declarations
CONTRACT = 2
SWEEP = Sweep("domain.load", "load f [1]", values=(0.0, -2.0, -8.0))  # pressed onto ψ
NORMS = ("h1", "l2")


def _states(model: Model, sol: Solution) -> np.ndarray:
    """(n_free,) "touch", "open" or "ambiguous", decided from the answer (`vi_core.states`):
    the force λ and the gap u − ψ, thresholds scaled by the achieved residual, the largest
    nodal force (λ or the elastic force Au: λ is all rounding when nothing touches) and the
    length scale max(|u|, |ψ|)."""
    force = float(np.abs(model.vi.A @ sol.u).max(initial=0.0))
    gap = model.vi.gap - model.vi.B @ sol.u  # (n_free,) u − ψ
    length = max(float(np.abs(sol.u).max(initial=0.0)), float(np.abs(model.vi.gap).max()))
    th = node_states.solution_thresholds(sol, max(float(sol.lam.max(initial=0.0)), force), length)
    return node_states.normal_states(sol.lam, gap, th)


def _touching(model: Model, sol: Solution) -> np.ndarray:
    """(n_free,) bool: nodes where the obstacle pushes (`_states`; ambiguous ones do not)."""
    return _states(model, sol) == "touch"


def draw(ax, model: Model, sol: Solution) -> str:
    """A panel of `mixvi figures`: u and ψ along the mid line, contact nodes marked."""
    P, u = model.mesh.points, model.full(sol.u)  # (n_nodes, 2), (n_nodes,)
    ymid, row = _mid_line(P)
    touch = np.zeros(model.mesh.n_nodes, dtype=bool)
    touch[model.free[_touching(model, sol)]] = True
    ax.plot(P[row, 0], u[row], "o-", ms=2, label="$u_h$")
    ax.plot(P[row, 0], model.psi[row], "k--", lw=1, label=r"obstacle $\psi$")
    on = row[touch[row]]
    ax.plot(P[on, 0], u[on], "r.", ms=5, label="contact")
    ax.set_xlabel(f"x (y = {ymid:.3g})")
    ax.legend(loc="best", fontsize=8)
    return f"{int(touch.sum())} nodes in contact"


mesh_size = scalar.mesh_size
exact_errors = scalar.exact_errors  # h1, l2 against the scene's [exact] table
reference_errors = scalar.reference_errors


def _counts(model: Model, sol: Solution) -> dict[str, int]:
    return {"contact": int(_touching(model, sol).sum())}


def extremes() -> list[ExtremeRow]:
    """An obstacle far below (no contact) and a load pressing the membrane onto it."""
    return [
        ExtremeRow(
            "obstacle far below (no contact)",
            "obstacle",
            ["domain.obstacle=-100.0"],
            level=0,
            checks=(expect(_counts, contact=0),),
        ),
        ExtremeRow(
            "load -1e3 (pressed onto the obstacle)",
            "obstacle",
            ["domain.load=-1000.0"],
            level=0,
            checks=(expect(_counts, contact="> 0"),),
        ),
    ]
