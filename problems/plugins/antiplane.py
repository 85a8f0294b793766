"""Plug-in: antiplane shear with Tresca friction on a rigid foundation (scalar).

The out-of-plane displacement w solves −μΔw = f₀ in Ω, w = w_D on Γ1, μ∂ₙw = f₂ on Γ2 and on
Γ3 the friction law |μ∂ₙw| ≤ g, with −μ∂ₙw = g w/|w| where w ≠ 0 (slip). Dual multipliers on
Γ3 (DESIGN.md §5): λ_h = Σ λ_i ψ_i, the rows of B are D_i e_iᵀ at the Γ3 nodes (D_i = ∫φ_i) and

    μK w + Bᵀλ = F,   Λ = Box(−g_i, g_i),   g_i = ∫gφ_i / D_i,

so λ_i = −μ∂ₙw is the friction traction: |λ_i| < g_i forces w_i = 0 (stick), w_i ≠ 0 needs
λ_i = g_i sign(w_i) (slip). Lemma 4.2 carries over: λᵀBw = Σ ∫gφ_i |w_i| = ∫g|w_h|_h.
Γ3 nodes with prescribed w (e.g. a corner shared with Γ1) carry no multiplier.

Scene tables: [domain] geometry, shear_modulus μ > 0, load f₀ (field); [[dirichlet]] boundary,
value; [[traction]] boundary, value (field f₂); [friction] boundary, g (field ≥ 0);
optional [solver] and [exact] (u = w, grad = [∂x w, ∂y w]: errors in summary.json).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from fem import assembly
from fem.boundary import Trace, trace
from fem.mesh import Mesh
from problems.errors import SceneError
from problems.output import plots
from problems.scene import Scene
from problems.scene.geometry import make_mesh
from vi_core import Box, MixedVI, Solution

from .contract import (
    ExtremeRow,
    Sweep,
    complementarity_defect,
    expect,
    read_boundaries,
    read_dirichlet,
    read_exact,
    read_head,
    read_solver,
)
from .transfer import nodal_reference_errors

NAME = "antiplane"
DESCRIPTION = "antiplane shear −μΔw = f with Tresca friction on a rigid foundation (scalar)"


@dataclass
class Model:
    """The assembled antiplane problem."""

    scene: Scene
    level: int
    mesh: Mesh
    vi: MixedVI
    free: np.ndarray  # (n_free,) node ids of the unknowns
    values: np.ndarray  # (n_nodes,) Dirichlet values (fixed nodes)
    tr: Trace  # the friction boundary Γ3
    rows: np.ndarray  # (m,) indices into tr.nodes that carry a multiplier
    g_weights: np.ndarray  # (m,) ∫gφ_i
    exact: tuple | None = None  # (w, grad) fields of the exact solution, if the scene has one
    options: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def dofs(self) -> dict[str, int]:
        return {"displacement": int(self.free.size), "multiplier": self.vi.m}

    def full(self, w: np.ndarray) -> np.ndarray:
        """(n_nodes,) nodal values including the Dirichlet data."""
        x = self.values.copy()
        x[self.free] = w
        return x

    def errors(self, sol: Solution) -> dict[str, float]:
        """|w − w_h|_H1 and ‖w − w_h‖_L2 against the scene's [exact] solution, and h."""
        if self.exact is None:
            raise ValueError(f"scene {self.scene.name!r} has no [exact] table")
        w, grad = self.exact
        x = self.full(sol.u)
        return {
            "h1": assembly.h1_seminorm_error(self.mesh, x, grad, 1),
            "l2": assembly.l2_error(self.mesh, x, w, 1),
            "h": self.mesh.h,
        }

    def complementarity(self, sol: Solution) -> float:
        """Relative defect of Lemma 4.2: λᵀBw = ∫g|w_h|_h."""
        w3 = self.full(sol.u)[self.tr.nodes[self.rows]]  # (m,)
        return complementarity_defect(sol.lam, self.vi.B @ sol.u, float(self.g_weights @ abs(w3)))


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model: mesh, μK, loads, Dirichlet reduction, friction rows on Γ3."""
    root = scene.root()
    default_level = read_head(root, NAME, 1)
    level = default_level if level is None else level
    dom = root.table("domain")
    mesh = make_mesh(dom.table("geometry"), level)
    mu = dom.number("shear_modulus", lo=0.0, lo_open=True)
    F = assembly.volume_load(mesh, dom.field("load", 1, 0.0), 1)  # (n_nodes,)
    dom.finish()
    fixed, values = read_dirichlet(root, mesh)
    for t in root.tables("traction"):
        for part in read_boundaries(t, "boundary", mesh.boundaries):
            F += assembly.boundary_load(mesh, part, t.field("value", 1), 1)
        t.finish()
    ft = root.table("friction")
    part = ft.string("boundary", choices=sorted(mesh.boundaries))
    g_fun = ft.field("g", 1)
    ft.finish()
    options = read_solver(root)
    exact = read_exact(root)
    root.finish()

    tr = trace(mesh, part)
    gw = assembly.boundary_load(mesh, part, g_fun, 1)[tr.nodes]  # (N,) ∫gφ_i
    if (g_fun(*mesh.points[tr.nodes].T) < 0).any() or (gw < 0).any():
        raise SceneError("friction.g", ft.raw("g"), "a friction bound g ≥ 0 everywhere on Γ3")
    rows = np.flatnonzero(~fixed[tr.nodes])  # (m,) Γ3 nodes with unknown w
    if rows.size == 0:
        raise SceneError("friction.boundary", part, "a boundary not entirely under [[dirichlet]]")
    free = np.flatnonzero(~fixed)
    K = mu * assembly.stiffness_matrix(mesh)
    col = np.full(mesh.n_nodes, -1)
    col[free] = np.arange(free.size)
    m = rows.size
    B = sp.csr_matrix(
        (tr.weights[rows], (np.arange(m), col[tr.nodes[rows]])), shape=(m, free.size)
    )  # (m, n_free): D_i at the Γ3 node i
    g_i = gw[rows] / tr.weights[rows]  # (m,)
    vi = MixedVI(
        A=K[free][:, free],
        B=B,
        f=F[free] - K[free][:, fixed] @ values[fixed],
        Lambda=Box(-g_i, g_i),
        X=(assembly.mass_matrix(mesh) + assembly.stiffness_matrix(mesh))[free][:, free],
        info={"scene": scene.name, "level": level},
    )
    return Model(scene, level, mesh, vi, free, values, tr, rows, gw[rows], exact, options)


def contact_state(model: Model, sol: Solution) -> dict:
    """Per-node quantities along Γ3 in the layout of `plots.contact_plots`."""
    w3 = model.full(sol.u)[model.tr.nodes[model.rows]]  # (m,)
    g = model.g_weights / model.tr.weights[model.rows]  # (m,) g_i
    slip = np.abs(sol.lam) >= g - 1e-9 * max(float(g.max(initial=0.0)), 1e-300)
    return {
        "s": model.tr.s[model.rows],
        "lam_t": sol.lam,
        "g": g,
        "jump_t": w3,
        "ut_slave": w3,
        "slip": slip,
    }


def postprocess(model: Model, sol: Solution, outdir: Path) -> dict:
    """antiplane.vtu (w) and the friction plots along Γ3 (multiplier with ±g, w)."""
    from fem.io import write_vtu

    w = model.full(sol.u)  # (n_nodes,)
    write_vtu(outdir / "antiplane.vtu", model.mesh, {"w": w})
    state = contact_state(model, sol)
    files = plots.contact_plots(state, outdir, title=f"{model.scene.name} (antiplane: w)")
    n, n_slip = state["slip"].size, int(state["slip"].sum())
    lemma = model.complementarity(sol)
    summary = {
        "contact": {"nodes": n, "stick": n - n_slip, "slip": n_slip},
        "lemma_4_2": lemma,
        "complementarity": lemma,
        "files": sorted([*files, "antiplane.vtu"]),
    }
    if model.exact is not None:
        summary["errors"] = model.errors(sol)
    return summary


# ------------------------------------------------------------------ contract v2 declarations
CONTRACT = 2
SWEEP = Sweep("friction.g", "friction bound g [Pa]", factors=(1.5, 1.0, 0.6))
NORMS = ("h1", "l2")


def draw(ax, model: Model, sol: Solution) -> str:
    """A panel of `mixvi figures`: λ with ±g, slip zones and w along Γ3."""
    return plots.friction_panel(ax, contact_state(model, sol))


def mesh_size(model: Model) -> float:
    """h of the built level."""
    return model.mesh.h


def exact_errors(model: Model, sol: Solution) -> dict[str, float] | None:
    """|w − w_h|_H1 and ‖w − w_h‖_L2 against the scene's [exact] table (None without one)."""
    if model.exact is None:
        return None
    err = model.errors(sol)
    return {k: err[k] for k in NORMS}


def reference_errors(model: Model, sol: Solution, ref: Model, ref_sol: Solution) -> dict:
    """‖w_h − w_ref‖ in H¹ and L² against the finer level `ref`."""
    return nodal_reference_errors(model.mesh, model.full(sol.u), ref.mesh, ref.full(ref_sol.u))


def _counts(model: Model, sol: Solution) -> dict[str, int]:
    slip = contact_state(model, sol)["slip"]
    return {"stick": int((~slip).sum()), "slip": int(slip.sum())}


def extremes() -> list[ExtremeRow]:
    """g = 0 (everything slips) and g × 1e6 (everything sticks)."""
    return [
        ExtremeRow(
            "g = 0 (frictionless)",
            "antiplane",
            ["friction.g=0.0"],
            level=0,
            checks=(expect(_counts, stick=0),),
        ),
        ExtremeRow(
            "g × 1e6 (tied)",
            "antiplane",
            ["friction.g=8e11"],
            level=0,
            checks=(expect(_counts, slip=0),),
        ),
    ]
