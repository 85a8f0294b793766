"""Plug-in: a linear elastic body in unilateral (Signorini) contact with a rigid obstacle, with
Tresca friction — the same solver as every other plug-in, only Λ differs.

On Γ3 (outward normals n_i, tangents τ_i, D_i = ∫φ_i) the rows of B are D_i n_iᵀu_i (normal)
and D_i τ_iᵀu_i (tangential); the obstacle lies at the normal distance gap(x) ≥ 0. With

    Λ = NonNegative(N) × Box(−g_i, g_i),    gap_B = [D_i gap(x_i); 0],

vi_core's (Bu − gap_B) ∈ N_Λ(λ) reads: u_n ≤ gap, pressure λ_n ≥ 0, λ_n (u_n − gap) = 0
(the body is pushed back, −Bᵀλ points along −n, only where it touches), and the Tresca law
|λ_τ| ≤ g_i, λ_τ = g_i sign(u_τ) where u_τ ≠ 0. Tresca's model with a given bound g acts on
all of Γ3, in contact or not. Lemma 4.2 becomes λᵀ(Bu − gap_B) = ∫g|u_τ|_h.

Scene tables: [body] as one [bodies.NAME] table of piezo_contact (an elastic material);
[contact] boundary, gap (field ≥ 0), g (field ≥ 0); optional [solver].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from pydantic import field_validator, model_validator
from pydantic_core import PydanticCustomError

from fem import assembly
from fem.boundary import Trace, trace
from fem.dirichlet import expand, reduce_dirichlet
from problems.errors import SceneError
from problems.output import plots, results
from problems.output.results import ContactTable
from problems.scene import Scene, SceneModel, Section
from problems.scene.fields import NonNegativeExpr, Text
from problems.scene.imported import require_curve
from problems.scene.model import head
from vi_core import Box, MixedVI, NonNegative, Solution, product

from .bodies import Body, BodySection, build_body
from .body_output import body_fields
from .contract import (
    ExtremeRow,
    Sweep,
    check_boundaries,
    check_meshed,
    complementarity_defect,
    expect,
)
from .fields import field_data
from .transfer import nodal_reference_errors

NAME = "signorini"
DESCRIPTION = "elastic body in unilateral contact with a rigid obstacle, Tresca friction"
Head = head(NAME, 1)


@dataclass
class Model:
    """The assembled Signorini–Tresca problem."""

    scene: Scene
    level: int
    body: Body
    vi: MixedVI
    free: np.ndarray  # (n_free,) full dof indices of the unknowns
    values: np.ndarray  # (2 n_nodes,) prescribed values (fixed dofs)
    tr: Trace  # Γ3
    B_full: sp.csr_matrix  # (2N, 2 n_nodes): normal rows, then tangential rows
    gap_n: np.ndarray  # (N,) nodal normal distance to the obstacle
    g_weights: np.ndarray  # (N,) ∫gφ_i
    options: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def dofs(self) -> dict[str, int]:
        return {"displacement": int(self.free.size), "multiplier": self.vi.m}

    def complementarity(self, sol: Solution) -> float:
        """Relative defect of Lemma 4.2: λᵀ(Bu − gap) = ∫g|u_τ|_h."""
        N = self.tr.size
        u_t = (self.B_full @ expand(sol.u, self.free, self.values))[N:] / self.tr.weights
        slack = self.vi.B @ sol.u - self.vi.gap  # (2N,)
        return complementarity_defect(sol.lam, slack, float(self.g_weights @ np.abs(u_t)))


class ContactSection(Section):
    """[contact]: the boundary Γ3, the normal gap to the obstacle (a field ≥ 0, m) and the
    friction bound g (a field ≥ 0, Pa)."""

    boundary: Text
    gap: NonNegativeExpr
    g: NonNegativeExpr


class ElasticBody(BodySection):
    """The [body] table: a body of an elastic (not piezoelectric) material."""

    @field_validator("material")
    @classmethod
    def _elastic(cls, v):
        if v.material().piezoelectric:
            raise PydanticCustomError("material", "an elastic (not piezoelectric) material")
        return v


class SignoriniScene(SceneModel):
    """A signorini scene: one elastic [body] and its [contact] with a rigid obstacle."""

    scene: Head
    body: ElasticBody
    contact: ContactSection

    @model_validator(mode="after")
    def _references(self) -> SignoriniScene:
        names = self.body.geometry.BOUNDARIES
        check_boundaries(["contact", "boundary"], [self.contact.boundary], names)
        return self


SCENE_MODEL = SignoriniScene


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model: elastic body, Dirichlet reduction, normal and tangential rows on Γ3."""
    spec = scene.validated(SCENE_MODEL)
    level = spec.scene.level if level is None else level
    body = build_body("body", spec.body, level, 0)
    ct = spec.contact
    part, gap_fun, g_fun = ct.boundary, ct.gap, ct.g
    check_meshed(body.mesh, [(ct.key("boundary"), part)])
    require_curve(body.mesh, part, ct.key("boundary"), part)
    options = spec.options()

    mesh = body.mesh
    tr = trace(mesh, part)
    N = tr.size
    x3, y3 = mesh.points[tr.nodes].T  # (N,) each
    gap_n = gap_fun(x3, y3)  # (N,)
    if (gap_n < 0).any():
        raise SceneError(gap_fun.path, gap_fun.source, "a distance ≥ 0 at every node of Γ3")
    gw = assembly.boundary_load(mesh, part, g_fun, 1)[tr.nodes]  # (N,) ∫gφ_i
    if (g_fun(x3, y3) < 0).any() or (gw < 0).any():
        raise SceneError(g_fun.path, g_fun.source, "a friction bound g ≥ 0 everywhere on Γ3")
    dofs = body.u_dofs(tr.nodes)  # (N, 2)
    rows = np.repeat(np.arange(2 * N), 2)  # (4N,)
    cols = np.concatenate([dofs, dofs]).ravel()  # (4N,)
    vals = (np.concatenate([tr.normals, tr.tangents]) * np.tile(tr.weights, 2)[:, None]).ravel()
    B_full = sp.csr_matrix((vals, (rows, cols)), shape=(2 * N, body.size))
    A, f, free = reduce_dirichlet(body.A, body.f, body.fixed, body.values)
    B = B_full[:, free]
    dead = np.flatnonzero(np.asarray(abs(B).sum(axis=1)).ravel() == 0)
    if dead.size:
        node = tr.nodes[dead[0] % N]
        raise SceneError(
            "contact.boundary",
            part,
            f"a contact boundary whose nodes are not clamped (node {node} at "
            f"{mesh.points[node].tolist()} has all displacement dofs prescribed)",
        )
    gap = np.concatenate([tr.weights * gap_n, np.zeros(N)])
    gap -= B_full[:, body.fixed] @ body.values[body.fixed]
    g_i = gw / tr.weights  # (N,)
    vi = MixedVI(
        A=A,
        B=B,
        f=f,
        Lambda=product(NonNegative(N), Box(-g_i, g_i)),
        gap=gap,
        X=body.X[free][:, free],
        info={"scene": scene.name, "level": level},
        **field_data([body], free, body.size),  # for the iterative linear path
    )
    return Model(scene, level, body, vi, free, body.values, tr, B_full, gap_n, gw, options)


def contact_state(model: Model, sol: Solution) -> dict:
    """Per-node quantities along Γ3: normal (pressure, u_n, gap) and tangential (plots layout)."""
    N = model.tr.size
    Bu = model.B_full @ expand(sol.u, model.free, model.values)  # (2N,)
    u_n, u_t = Bu[:N] / model.tr.weights, Bu[N:] / model.tr.weights  # (N,) each
    lam_n, lam_t = sol.lam[:N], sol.lam[N:]
    g = model.g_weights / model.tr.weights
    slip = np.abs(lam_t) >= g - 1e-9 * max(float(g.max(initial=0.0)), 1e-300)
    # beyond rounding of the largest force, λ_n or the elastic Au (all rounding when apart)
    force = float(np.abs(model.vi.A @ sol.u).max(initial=0.0))
    touch = lam_n > 1e-9 * max(float(lam_n.max(initial=0.0)), force, 1e-300)
    return {
        "s": model.tr.s,
        "lam_n": lam_n,
        "lam_t": lam_t,
        "g": g,
        "u_n": u_n,
        "gap": model.gap_n,
        "jump_t": u_t,
        "ut_slave": u_t,
        "slip": slip,
        "touch": touch,
    }


def contact_table(model: Model, sol: Solution) -> ContactTable:
    """One row per node of Γ3: λ, u·τ (the jump against the fixed obstacle), the remaining
    gap gap0 − u·n, and the state: open where the node does not touch, else stick or slip."""
    st = contact_state(model, sol)
    state = np.where(st["touch"], np.where(st["slip"], "slip", "stick"), "open")
    return ContactTable(
        points=model.body.mesh.points[model.tr.nodes],
        normals=model.tr.normals,
        weights=model.tr.weights,
        segments=model.tr.segments,
        lambda_n=st["lam_n"],
        lambda_t=st["lam_t"],
        jump_t=st["jump_t"],
        state=state,
        gap=np.maximum(st["gap"] - st["u_n"], 0.0),
    )


def fields(model: Model, sol: Solution) -> dict[str, np.ndarray]:
    """Nodal fields: "displacement" (n_nodes, 2)."""
    u, _ = model.body.split(expand(sol.u, model.free, model.values))
    return {"displacement": u}


def postprocess(model: Model, sol: Solution, outdir: Path) -> dict:
    """signorini.vtu (displacement, stress), the contact line (contact.vtu, contact.csv),
    friction plots and contact_normal.png."""
    from fem.io import write_vtu

    b = model.body
    point, cell, note = body_fields(b, expand(sol.u, model.free, model.values))
    write_vtu(outdir / "signorini.vtu", b.mesh, point, cell)
    table = contact_table(model, sol)
    results.write_contact_csv(outdir / "contact.csv", table)
    results.write_contact_vtu(outdir / "contact.vtu", table)
    st = contact_state(model, sol)
    files = plots.contact_plots(st, outdir, title=f"{model.scene.name} (tangential)")
    files.append(_normal_plot(st, outdir, model.scene.name))
    n, n_touch = st["slip"].size, int(st["touch"].sum())
    lemma = model.complementarity(sol)
    totals = table.totals()  # stick and slip among the touching nodes; the others open
    out = {
        "contact": {
            "nodes": n,
            **{k: totals["counts"][k] for k in ("stick", "slip", "open")},
            **totals,
            "table": table.records(),
        },
        "signorini": {"nodes": n, "in_contact": n_touch, "separated": n - n_touch},
        "lemma_4_2": lemma,
        "complementarity": lemma,
        "files": sorted([*files, "signorini.vtu", "contact.csv", "contact.vtu"]),
    }
    if note:
        out["notes"] = [note]
    return out


def _normal_plot(st: dict, outdir: Path, title: str) -> str:
    import matplotlib.pyplot as plt  # backend Agg, set by `plots`

    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(st["s"], st["lam_n"], "o-", ms=3, label=r"pressure $\lambda_n$")
    ax.set_xlabel("arc length along $\\Gamma_3$ [m]")
    ax.set_ylabel(r"$\lambda_n$ [Pa]")
    ax2 = ax.twinx()
    ax2.plot(st["s"], st["u_n"], "s-", ms=2, color="tab:orange", label="$u_n$")
    ax2.plot(st["s"], st["gap"], "k--", lw=1, label="gap")
    ax2.set_ylabel("normal displacement, gap [m]")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="best", fontsize=8)
    ax.set_title(f"{title}: {int(st['touch'].sum())} of {st['touch'].size} nodes in contact")
    fig.tight_layout()
    fig.savefig(outdir / "contact_normal.png", dpi=120)
    plt.close(fig)
    return "contact_normal.png"


# ------------------------------------------------------------------ contract v2 declarations
CONTRACT = 2
SWEEP = Sweep("contact.g", "friction bound g [Pa]", factors=(1.5, 1.0, 0.6))
NORMS = ("u_H1", "u_L2")


def draw(ax, model: Model, sol: Solution) -> str:
    """A panel of `mixvi figures`: λ·τ with ±g, slip zones and u·τ along Γ3."""
    st = contact_state(model, sol)
    note = plots.friction_panel(ax, st)
    return f"{note}, {int(st['touch'].sum())} of {st['touch'].size} touching"


def mesh_size(model: Model) -> float:
    """h of the built level."""
    return model.body.mesh.h


def reference_errors(model: Model, sol: Solution, ref: Model, ref_sol: Solution) -> dict:
    """‖u_h − u_ref‖ in H¹ and L² against the finer level `ref` (no exact solution known)."""

    def disp(m: Model, u: np.ndarray) -> np.ndarray:
        return m.body.split(expand(u, m.free, m.values))[0]  # (n_nodes, 2)

    e = nodal_reference_errors(
        model.body.mesh, disp(model, sol.u), ref.body.mesh, disp(ref, ref_sol.u)
    )
    return {"u_H1": e["h1"], "u_L2": e["l2"]}


def _counts(model: Model, sol: Solution) -> dict[str, int]:
    st = contact_state(model, sol)
    return {
        "stick": int((~st["slip"]).sum()),
        "slip": int(st["slip"].sum()),
        "in_contact": int(st["touch"].sum()),
    }


def extremes() -> list[ExtremeRow]:
    """Frictionless, tied, and an obstacle too far away to touch."""
    return [
        ExtremeRow(
            "g = 0 (frictionless)",
            "signorini",
            ["contact.g=0.0"],
            level=0,
            checks=(expect(_counts, stick=0, in_contact="> 0"),),
        ),
        ExtremeRow(
            "g × 1e6 (tied where touching)",
            "signorini",
            ["contact.g=5e11"],
            level=0,
            checks=(expect(_counts, slip=0, in_contact="> 0"),),
        ),
        ExtremeRow(
            # 1 cm, 50 × the prescribed displacement 2e-4 m: with 1 m Clarabel's raw answer stops at
            # residual 1.8e-6 and differs from ssn's by 0.11 (measured; conic's scaling)
            "obstacle 1 cm below (no contact)",
            "signorini",
            ["contact.gap=1e-2"],
            level=0,
            checks=(expect(_counts, in_contact=0),),
        ),
    ]
