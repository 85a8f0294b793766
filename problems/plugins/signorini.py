"""Plug-in: a linear elastic body in unilateral (Signorini) contact with a rigid obstacle, with
Tresca friction where it touches or Coulomb friction — a scene preset of the contact plug-in.

A signorini scene ([body], [contact] boundary, gap, friction, g or F) is built as the 2D
contact scene with that one body and [contact] slave = "body.BOUNDARY", master = "rigid", law =
"unilateral", ends = "keep" (`problems.plugins.contact.plane.build_model`): one implementation
of the contact laws (docs/coulomb.md, "Contact laws of the plug-ins"). With ends = "keep" the dual
mortar rows of a rigid obstacle are the lumped rows D_i n_iᵀu_i, D_i τ_iᵀu_i (D_i = ∫φ_i), and
vi_core's conditions read, node by node: u_n ≤ gap, pressure λ_n ≥ 0, λ_n (u_n − gap) = 0, and
|λ_τ| ≤ g_i where the node touches (λ_τ = 0 where it is apart; Coulomb: |λ_τ| ≤ F_i λ_n), with
λ_τ = ρ sign(u_τ) where u_τ ≠ 0. Lemma 4.2 becomes λᵀ(Bu − gap_B) = Σ_i ρ_i D_i |u_τ,i|.

Tresca acts only where the body touches (UnilateralTresca, contact-only; it once acted on all of
Γ3, touching or not): a quasi-variational set, solved by ssn directly and by the fixed point on
Tresca problems (vi_core.tresca_fixed_point), not by conic or homotopy directly.

Scene tables: [body] as one [bodies.NAME] table of a contact scene (an elastic material);
[contact] boundary, gap (field ≥ 0), friction ("tresca" with g, or "coulomb" with F);
optional [solver].
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import field_validator, model_validator
from pydantic_core import PydanticCustomError

from problems.errors import SceneError
from problems.output import plots
from problems.scene import Scene, SceneModel
from problems.scene.fields import NonNegativeExpr, Text
from problems.scene.geometry import PlaneGeometry
from problems.scene.model import head
from vi_core import Solution

from .contact import plane as pc
from .contact import scene_model
from .contact.bodies import BodySection
from .contact.error_estimate import estimate as _estimate
from .contact.law import FrictionLaw
from .contract import ExtremeRow, Sweep, check_boundaries, expect
from .transfer import nodal_reference_errors

NAME = "signorini"
DESCRIPTION = "elastic body in unilateral contact with a rigid obstacle, Tresca or Coulomb friction"
Head = head(NAME, 1)


class Model(pc.Model):
    """The contact plug-in's (2D) Model of the preset, with its Lemma 4.2 identity."""

    def complementarity(self, sol: Solution) -> float:
        """Relative defect of Lemma 4.2: λᵀ(Bu − gap) = Σ_i ρ_i D_i |u_τ,i|."""
        return pc.contact_state(self, sol)["lemma_4_2"]


class ContactSection(FrictionLaw):
    """[contact]: the boundary Γ3, the normal gap to the obstacle (a field ≥ 0, m) and the
    friction: "tresca" with the bound g (a field ≥ 0, Pa; acts where the body touches) or
    "coulomb" with the coefficient F (a field ≥ 0)."""

    boundary: Text
    gap: NonNegativeExpr


class ElasticBody(BodySection):
    """The [body] table: a 2D body of an elastic (not piezoelectric) material."""

    geometry: PlaneGeometry

    @field_validator("material")
    @classmethod
    def _elastic(cls, v):
        if v.piezoelectric:
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
BODY = "body"  # the body's name in the contact model


def piezo_spec(spec: SignoriniScene) -> scene_model.ContactScene:
    """The contact scene model (2D) of a validated signorini scene (module docstring); its
    expressions keep their signorini field paths for the errors of the build."""
    ct = spec.contact
    contact = scene_model.ContactSection.model_construct(
        slave=f"{BODY}.{ct.boundary}",
        master="rigid",
        law="unilateral",
        friction=ct.friction,
        g=ct.g,
        F=ct.F,
        gap=ct.gap,
        ends="keep",
    )
    contact._path = "contact"
    return scene_model.ContactScene.model_construct(
        format=2,
        scene=spec.scene,
        solver=spec.solver,
        bodies={BODY: spec.body},
        contact=contact,
        output=None,
        exact=None,
    )


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → the contact plug-in's (2D) Model of its preset (module docstring)."""
    spec = scene.validated(SCENE_MODEL)
    try:
        return pc.build_model(piezo_spec(spec), scene, level, Model)
    except SceneError as err:
        if err.key == "contact.slave":  # the preset's slave is signorini's contact.boundary
            err = SceneError("contact.boundary", spec.contact.boundary, err.allowed, err.file)
        raise (err if err.file else err.in_file(scene.path)) from None


warm_start = pc.warm_start
incremental = pc.incremental  # load paths: friction on the slip since the previous step
step_output = pc.step_output


contact_state = pc.contact_state
contact_table = pc.contact_table


def fields(model: Model, sol: Solution) -> dict[str, np.ndarray]:
    """Nodal fields: "displacement" (n_nodes, 2)."""
    return {"displacement": pc.fields(model, sol)[f"{BODY}.displacement"]}


def postprocess(model: Model, sol: Solution, outdir: Path) -> dict:
    """The contact plug-in's files (body.vtu, contact.csv/.vtu, results.pvd, friction plots), the
    normal plot contact_normal.png and the summary entry "signorini" (nodes in contact)."""
    out = pc.postprocess(model, sol, outdir)
    st = contact_state(model, sol)
    normal = st["normal_state"]  # (N_n,) touch, open or ambiguous (vi_core.states)
    out["files"] = sorted([*out["files"], _normal_plot(st, outdir, model.scene.name)])
    out["signorini"] = {
        "nodes": int(normal.size),
        "in_contact": int(np.sum(normal == "touch")),
        "separated": int(np.sum(normal == "open")),
        "ambiguous": int(np.sum(normal == "ambiguous")),
    }
    out["complementarity"] = model.complementarity(sol)
    return out


def _normal_plot(st: dict, outdir: Path, title: str) -> str:
    plt = plots.pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(st["s_n"], st["lam_n"], "o-", ms=3, label=r"pressure $\lambda_n$")
    ax.set_xlabel("arc length along $\\Gamma_3$ [m]")
    ax.set_ylabel(r"$\lambda_n$ [Pa]")
    ax2 = ax.twinx()
    ax2.plot(st["s_n"], st["u_n"], "s-", ms=2, color="tab:orange", label="$u_n$")
    ax2.plot(st["s_n"], st["gap"], "k--", lw=1, label="gap")
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


mesh_size = pc.mesh_size


def reference_errors(model: Model, sol: Solution, ref: Model, ref_sol: Solution) -> dict:
    """‖u_h − u_ref‖ in H¹ and L² against the finer level `ref` (no exact solution known)."""
    u, u_ref = fields(model, sol)["displacement"], fields(ref, ref_sol)["displacement"]
    e = nodal_reference_errors(model.bodies[0].mesh, u, ref.bodies[0].mesh, u_ref)
    return {"u_H1": e["h1"], "u_L2": e["l2"]}


def _counts(model: Model, sol: Solution) -> dict[str, int]:
    st = contact_state(model, sol)
    return {
        "stick": int(np.sum(st["state"] == "stick")),
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


def estimate(model: Model, sol: Solution) -> dict:
    """A posteriori error indicators per cell (`contact.error_estimate.estimate`)."""
    return _estimate(lambda scene: piezo_spec(scene.validated(SCENE_MODEL)), model, sol)
