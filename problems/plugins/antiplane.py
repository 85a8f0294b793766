"""Plug-in: antiplane shear with Tresca friction on a rigid foundation (scalar).

The out-of-plane displacement w solves −μΔw = f₀ in Ω, w = w_D on Γ1, μ∂ₙw = f₂ on Γ2 and on
Γ3 the friction law |μ∂ₙw| ≤ g, with −μ∂ₙw = g w/|w| where w ≠ 0 (slip). Dual multipliers on
Γ3 (docs/design.md §3): λ_h = Σ λ_i ψ_i, the rows of B are D_i e_iᵀ at the Γ3 nodes (D_i = ∫φ_i) and

    μK w + Bᵀλ = F,   Λ = Box(−g_i, g_i),   g_i = ∫gφ_i / D_i,

so λ_i = −μ∂ₙw is the friction traction: |λ_i| < g_i forces w_i = 0 (stick), w_i ≠ 0 needs
λ_i = g_i sign(w_i) (slip). Lemma 4.2 carries over: λᵀBw = Σ ∫gφ_i |w_i| = ∫g|w_h|_h.
Γ3 nodes with prescribed w (e.g. a corner shared with Γ1) carry no multiplier.

Scene tables: [domain] geometry, shear_modulus μ > 0, load f₀ (field); [[dirichlet]] boundary,
value; [[traction]] boundary, value (field f₂); [friction] boundary, g (field ≥ 0);
optional [solver] and [exact] (u = w, grad = [∂x w, ∂y w]: errors in summary.json).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import scipy.sparse as sp
from pydantic import BeforeValidator, Field, model_validator

from fem import assembly
from fem.facets import Trace, trace
from problems.errors import SceneError
from problems.output import plots, results
from problems.output.results import ContactTable
from problems.scene import Scene, SceneModel, Section
from problems.scene.fields import Expression, NonNegativeExpr, Number, Text
from problems.scene.geometry import PlaneGeometry
from problems.scene.imported import require_curve
from problems.scene.model import head, one_or_many
from vi_core import Box, MixedVI, Solution
from vi_core import states as node_states

from . import scalar
from .contract import (
    Boundaries,
    DirichletPart,
    ExtremeRow,
    ScalarExact,
    Sweep,
    check_boundaries,
    complementarity_defect,
    dirichlet,
    expect,
)
from .scalar import ScalarModel

NAME = "antiplane"
DESCRIPTION = "antiplane shear −μΔw = f with Tresca friction on a rigid foundation (scalar)"
Head = head(NAME, 1)


@dataclass
class Model(ScalarModel):
    """The assembled antiplane problem."""

    tr: Trace  # the friction boundary Γ3
    rows: np.ndarray  # (m,) indices into tr.nodes that carry a multiplier
    g_weights: np.ndarray  # (m,) ∫gφ_i

    def complementarity(self, sol: Solution) -> float:
        """Relative defect of Lemma 4.2: λᵀBw = ∫g|w_h|_h."""
        w3 = self.full(sol.u)[self.tr.nodes[self.rows]]  # (m,)
        return complementarity_defect(sol.lam, self.vi.B @ sol.u, float(self.g_weights @ abs(w3)))


class Domain(Section):
    """[domain]: geometry, shear modulus μ > 0 (Pa), load f₀ (a field)."""

    geometry: PlaneGeometry
    shear_modulus: Annotated[Number, Field(gt=0.0)]
    load: Expression = Expression(0.0)


class TractionPart(Section):
    """A [[traction]] table: boundary part(s) and the traction f₂ there (a field)."""

    boundary: Boundaries
    value: Expression


class Friction(Section):
    """[friction]: the boundary Γ3 and the friction bound g (a field ≥ 0)."""

    boundary: Text
    g: NonNegativeExpr


class AntiplaneScene(SceneModel):
    """An antiplane scene: [domain], [[dirichlet]], [[traction]], [friction], [exact]."""

    scene: Head
    domain: Domain
    dirichlet: Annotated[list[DirichletPart], BeforeValidator(one_or_many), Field(min_length=1)]
    traction: Annotated[list[TractionPart], BeforeValidator(one_or_many)] = []
    friction: Friction
    exact: ScalarExact | None = None

    @model_validator(mode="after")
    def _references(self) -> AntiplaneScene:
        scalar.check_parts(self, ("dirichlet", "traction"))
        names = self.domain.geometry.BOUNDARIES
        check_boundaries(["friction", "boundary"], [self.friction.boundary], names)
        return self


SCENE_MODEL = AntiplaneScene


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model: mesh, μK, loads, Dirichlet reduction, friction rows on Γ3."""
    spec = scene.validated(SCENE_MODEL)
    level = spec.scene.level if level is None else level
    friction = (spec.friction.key("boundary"), spec.friction.boundary)
    mesh = scalar.meshed(spec, level, ("dirichlet", "traction"), [friction])
    require_curve(mesh, friction[1], *friction)
    mu = spec.domain.shear_modulus
    F = assembly.volume_load(mesh, spec.domain.load, 1)  # (n_nodes,)
    fixed, values = dirichlet(spec.dirichlet, mesh)
    for t in spec.traction:
        for part in t.boundary:
            F += assembly.boundary_load(mesh, part, t.value, 1)
    part, g_fun = spec.friction.boundary, spec.friction.g
    options = spec.options()
    exact = None if spec.exact is None else spec.exact.compiled()

    tr = trace(mesh, part)
    gw = assembly.boundary_load(mesh, part, g_fun, 1)[tr.nodes]  # (N,) ∫gφ_i
    if (g_fun(*mesh.points[tr.nodes].T) < 0).any() or (gw < 0).any():
        raise SceneError(g_fun.path, g_fun.source, "a friction bound g ≥ 0 everywhere on Γ3")
    rows = np.flatnonzero(~fixed[tr.nodes])  # (m,) Γ3 nodes with unknown w
    if rows.size == 0:
        raise SceneError("friction.boundary", part, "a boundary not entirely under [[dirichlet]]")
    free, A, f, X = scalar.reduced(mesh, F, fixed, values, mu)
    col = np.full(mesh.n_nodes, -1)
    col[free] = np.arange(free.size)
    m = rows.size
    B = sp.csr_matrix(
        (tr.weights[rows], (np.arange(m), col[tr.nodes[rows]])), shape=(m, free.size)
    )  # (m, n_free): D_i at the Γ3 node i
    g_i = gw[rows] / tr.weights[rows]  # (m,)
    vi = MixedVI(
        A=A,
        B=B,
        f=f,
        Lambda=Box(-g_i, g_i),
        X=X,
        info={"scene": scene.name, "level": level},
    )
    return Model(
        scene, level, mesh, vi, free, values, tr, rows, gw[rows], exact=exact, options=options
    )


def contact_state(model: Model, sol: Solution) -> dict:
    """Per-node quantities along Γ3 in the layout of `plots.contact_plots`; "state" (m,) stick,
    slip or ambiguous from the answer (`vi_core.states`: the margin g − |λ| and the slip |w|,
    thresholds scaled by the achieved residual), "slip" the slip nodes."""
    w3 = model.full(sol.u)[model.tr.nodes[model.rows]]  # (m,)
    g = model.g_weights / model.tr.weights[model.rows]  # (m,) g_i
    lam_scale = max(float(np.abs(sol.lam).max(initial=0.0)), float(g.max(initial=0.0)))
    th = node_states.solution_thresholds(sol, lam_scale, float(np.abs(sol.u).max(initial=0.0)))
    state = node_states.tangential_states(sol.lam, g, w3, th)  # (m,)
    return {
        "state": state,
        "slip": state == "slip",
        "s": model.tr.s[model.rows],
        "lam_t": sol.lam,
        "g": g,
        "jump_t": w3,
        "ut_slave": w3,
        **PLOT_LABELS,
    }


# the plots' words for antiplane: the friction acts along e_z, not along an in-plane tangent
PLOT_LABELS = {
    "lam_label": r"friction traction $\lambda = -\mu\,\partial w/\partial n$ [Pa]",
    "jump_label": "out-of-plane displacement (slip) w [m]",
    "ut_label": "out-of-plane displacement w [m]",
    "tangent_note": r"sign convention: $w$ and $\lambda$ point along $e_z$, out of the plane; "
    r"$\lambda > 0$: the foundation pulls the body along $-e_z$; arc length runs with the body "
    "on the left",
}


def fields(model: Model, sol: Solution) -> dict[str, np.ndarray]:
    """Nodal fields: "w" (n_nodes,), the out-of-plane displacement."""
    return {"w": model.full(sol.u)}


# the columns of antiplane's contact.csv in its own terms (the tangent is e_z, out of plane)
CONTACT_MEANINGS = {
    "tangent_x": "the friction direction: e_z, out of the plane (antiplane shear)",
    "lambda_t": "friction traction lambda = -mu dw/dn along e_z (the foundation's traction "
    "on the body is -lambda e_z); |lambda_t| <= g; empty where w is prescribed",
    "jump_t": "slip: the out-of-plane displacement w against the rigid foundation",
}


def contact_table(model: Model, sol: Solution) -> ContactTable:
    """One row per node of Γ3 (problems.output.results): λ and w along e_z, stick or slip;
    nodes with prescribed w carry no multiplier (state no_multiplier, λ empty)."""
    tr, k = model.tr, model.tr.size
    st = contact_state(model, sol)
    lam = np.full(k, np.nan)  # (k,)
    lam[model.rows] = st["lam_t"]
    state = np.full(k, "no_multiplier", dtype=object)
    state[model.rows] = st["state"]
    tangents = np.zeros((k, 1, 3))  # (k, 1, 3): e_z at every node
    tangents[:, 0, 2] = 1.0
    return ContactTable(
        points=model.mesh.points[tr.nodes],
        normals=tr.normals,
        weights=tr.weights,
        segments=tr.facets,
        lambda_n=None,
        lambda_t=lam,
        jump_t=model.full(sol.u)[tr.nodes],
        state=state.astype(str),
        tangents=tangents,
        meanings=CONTACT_MEANINGS,
    )


def postprocess(model: Model, sol: Solution, outdir: Path) -> dict:
    """antiplane.vtu (w), the friction line (contact.csv, contact.vtu) and the friction plots
    along Γ3 (multiplier with ±g, w)."""
    from fem.io import write_vtu

    w = model.full(sol.u)  # (n_nodes,)
    write_vtu(outdir / "antiplane.vtu", model.mesh, {"w": w})
    state = contact_state(model, sol)
    files = plots.contact_plots(state, outdir, title=f"{model.scene.name} (antiplane: w)")
    written, contact = results.write_contact(outdir, contact_table(model, sol))
    lemma = model.complementarity(sol)
    summary = {
        "contact": contact,
        "lemma_4_2": lemma,
        "complementarity": lemma,
        "files": sorted([*files, *written, "antiplane.vtu"]),
        "warnings": node_states.warnings(state["state"]),
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


mesh_size = scalar.mesh_size
exact_errors = scalar.exact_errors  # h1, l2 against the scene's [exact] table
reference_errors = scalar.reference_errors


def _counts(model: Model, sol: Solution) -> dict[str, int]:
    state = contact_state(model, sol)["state"]
    return {"stick": int(np.sum(state == "stick")), "slip": int(np.sum(state == "slip"))}


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
