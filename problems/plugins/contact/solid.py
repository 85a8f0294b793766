"""The 3D front of the contact plug-in: elastic or piezoelectric 3D bodies in bilateral
contact with Tresca friction, or in unilateral contact with Tresca (where touching) or Coulomb
friction discs. Its build, contact state, result files and contract declarations; the contact
interface itself (surface, frames, crosspoint rules, rows) is `surface_contact`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from problems.scene import Scene
from vi_core import Solution
from vi_core import states as node_states

from . import checks, errors, interface, warm_starts
from . import extremes as contact_extremes
from . import model as contact_model
from . import solid_output as contact3d_output
from .model import BodiesModel
from .scene_model import ContactScene, count, update  # noqa: F401 (contract)
from .surface_contact import from_scene

NAME = "contact"  # the unified plug-in (problems.plugins.contact); 3D front
ALIAS = "contact3d"  # its former name, still accepted (registry.ALIASES)
DIMENSION = 3  # the models' `dimension` (`count` needs no model to tell it)
DESCRIPTION = (
    "elastic/piezoelectric 3D bodies in bilateral Tresca or unilateral Tresca/Coulomb contact "
    "(friction discs)"
)
CONTRACT = 2


@dataclass
class Model(BodiesModel):
    """A built 3D scene: the mixed VI plus what post-processing needs."""

    dimension: int = DIMENSION


SCENE_MODEL = ContactScene  # one scene model for 2D and 3D (`scene_model`)


__getattr__ = contact_model.moved_names(
    __name__,
    {
        "SolidScene": ("problems.plugins.contact.scene_model", "ContactScene"),
        "ContactSection": ("problems.plugins.contact.scene_model", "ContactSection"),
    },
)


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model (meshes, assembly, Dirichlet reduction, contact rows, MixedVI); a
    SceneError raised while building names the scene file."""
    return contact_model.built(_build, scene, level)


def _build(scene: Scene, level: int | None) -> Model:
    spec = scene.validated(SCENE_MODEL, DIMENSION)
    return contact_model.assemble(spec, scene, level, from_scene, Model)


incremental = contact_model.incremental


# ------------------------------------------------------------------ post-processing
def contact_state(model: Model, sol: Solution) -> dict:
    """Per surface node (k): lam_n, lam_t1, lam_t2 (NaN where not carried), lam_t_vec (k, 3),
    jump_n, jump_t1, jump_t2 ((Bu)/W in the frame: the slave displacement for a rigid
    foundation, the mortar jump with a master), g (the friction radius of the solution: g;
    unilateral Tresca g where the node is not open, 0 elsewhere; Coulomb F·λ_n), gap (the
    remaining normal gap (gap₀ − [u]_n), unilateral; NaN elsewhere), and the states, which
    follow from the answer by one rule (`vi_core.states`: multiplier margin and gap/slip,
    thresholds scaled by the achieved residual): state (stick, slip, normal_only, open,
    ambiguous, no_multiplier), touch (k,) bool (touch evidence: every node with rows for
    bilateral contact), slip (k,) bool; `pressure` the pressure scale; the Lemma 4.2
    identity λᵀ(B u − gap₀) = Σ_k ρ_k W_t,k |[u]_t,k| ([u]_t since the previous load step on a
    load path: `incremental`) and its relative defect (unilateral: relative
    to the larger of Σρ W|[u]_t| and the pressure scale times Σ|B u − gap₀|)."""
    c = model.contact
    k = c.tr.size
    idx_n, idx_b, idx_l = c.rows()
    lam = sol.lam
    radius = c.bound(lam)  # (k,) the friction radius at λ
    j = interface.jumps(model, sol, radius, lambda: c.W.min())  # W: the nodal weights (areas)
    Bu, Bi = j.Bu, j.Bi  # (m,) each
    out = {
        key: np.full(k, np.nan)
        for key in ("lam_n", "lam_t1", "lam_t2", "jump_n", "jump_t1", "jump_t2")
    }
    Wt = c.W_t  # the tangential rows' ∫ψ̃_k
    out["lam_n"][c.rows_n] = lam[idx_n]
    out["jump_n"][c.rows_n] = Bu[idx_n] / c.W_n[c.rows_n]
    lb = lam[idx_b]  # (N_b, 2)
    jb = Bu[idx_b] / Wt[c.disc, None]  # (N_b, 2)
    out["lam_t1"][c.disc], out["lam_t2"][c.disc] = lb[:, 0], lb[:, 1]
    out["jump_t1"][c.disc], out["jump_t2"][c.disc] = jb[:, 0], jb[:, 1]
    ll, jl = lam[idx_l], Bu[idx_l] / Wt[c.line]
    for slot, (lk, jk) in enumerate((("lam_t1", "jump_t1"), ("lam_t2", "jump_t2"))):
        sel = c.line_slot == slot
        out[lk][c.line[sel]] = ll[sel]
        out[jk][c.line[sel]] = jl[sel]
    # the tangential multiplier as a vector: disc nodes t1, t2; line nodes their kept tangent
    vec = np.zeros((k, 3))
    vec[c.disc] = lb[:, :1] * c.t1[c.disc] + lb[:, 1:] * c.t2[c.disc]
    vec[c.line] = ll[:, None] * c.line_dir
    jvec = np.zeros((k, 3))
    jvec[c.disc] = jb[:, :1] * c.t1[c.disc] + jb[:, 1:] * c.t2[c.disc]
    jvec[c.line] = jl[:, None] * c.line_dir
    has_t = np.zeros(k, dtype=bool)
    has_t[c.disc] = has_t[c.line] = True
    has_n = np.isin(np.arange(k), c.rows_n)  # (k,) nodes carrying a normal row
    gap = np.full(k, np.nan)
    if c.law == "unilateral":
        gap[c.rows_n] = (c.gap0 - Bu[idx_n]) / c.W_n[c.rows_n]  # the remaining normal gap
    ji = np.zeros((k, 2))  # the tangential jump (since the origin) in the node's frame
    ji[c.disc] = Bi[idx_b] / Wt[c.disc, None]
    ji[c.line, 0] = Bi[idx_l] / Wt[c.line]
    jt = np.linalg.norm(ji, axis=1)  # (k,)
    th = j.th  # the states from the answer (vi_core.states)
    normal = np.full(k, "touch", dtype=object)  # bilateral: every node with rows touches
    if c.law == "unilateral":
        normal[c.rows_n] = node_states.normal_states(lam[idx_n], gap[c.rows_n], th)
    rows = has_n | has_t  # (k,) nodes carrying rows
    touch = (normal == "touch") & rows  # (k,)
    rho = radius * ((normal != "open") & rows)  # (k,) the friction radius; none where open
    mag = np.linalg.norm(vec, axis=1)  # (k,) |λ_t|
    tang = node_states.tangential_states(mag, rho, jt, th)
    state = np.full(k, "no_multiplier", dtype=object)
    state[rows] = node_states.node_states(normal, tang, has_t)[rows]
    slip = state == "slip"
    g_abs = float(np.sum((rho * Wt * jt)[has_t]))
    return {
        **out,
        "lam_t_vec": vec,
        "jump_t_vec": jvec,
        "g": rho,
        "has_t": has_t,
        "touch": touch,
        "gap": gap,
        "pressure": j.pressure,
        "slip": slip,
        "state": state.astype(str),
        **interface.lemma_4_2(lam, j, g_abs, float(np.sum(rho * Wt))),
    }


def postprocess(model: Model, sol: Solution, outdir: Path) -> dict:
    """Write the body VTUs, the contact surface (contact.vtu), contact.csv, results.pvd and
    the stick/slip map into `outdir`; return the summary entries."""
    summary = contact3d_output.write(model, sol, outdir, contact_state)
    summary["checks"] = checks.solution_checks(model, sol)
    return summary


# ------------------------------------------------------------------ contract v2 declarations
fields = contact_model.fields  # nodal fields by name
mesh_size = contact_model.mesh_size  # h of the built level
SWEEP = contact_model.friction_sweep("g_sweep3d.png", "F_sweep3d.png")
NORMS = errors.REFERENCE_NORMS[DIMENSION]  # against a finer level: reference_errors
EXACT_NORMS = errors.EXACT_NORMS  # against the scene's [exact] table: exact_errors
exact_errors = partial(errors.exact_errors, SCENE_MODEL, contact_state)
reference_errors = partial(errors.reference_errors, contact_state)
warm_start = partial(warm_starts.over_surface, contact_state)  # nested iteration
extremes = contact_extremes.rows_3d


def draw(ax, model: Model, sol: Solution) -> str:
    """A panel of `mixvi figures`: the stick/slip map of the contact surface."""
    if model.contact is None:
        return "no contact interface"
    st = contact_state(model, sol)
    uv, _, _ = contact3d_output.chart(model)
    for s, col in (("stick", "tab:blue"), ("slip", "tab:red")):
        sel = st["state"] == s
        ax.scatter(uv[sel, 0], uv[sel, 1], s=8, color=col, label=f"{s} ({int(sel.sum())})")
    ax.set_aspect("equal")
    ax.legend(fontsize=7)
    return f"slip {int(st['slip'].sum())} of {int(st['has_t'].sum())} nodes"
