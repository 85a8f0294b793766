"""Result files and summary entries of the 2D contact front (`plane`): a VTU per body
(`body_output.write_bodies`), contact.csv and contact.vtu (`problems.output.results`, one row
per slave node of Γ3), the friction plots, the potential along a boundary, and the summary's
contact, interface, Lemma 4.2, electrical and warning entries."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fem.facets import trace
from problems.output import plots, results
from problems.output.results import ContactTable
from vi_core import Solution

from . import balance as piezo_balance
from . import electrical as electrical_contact
from . import interface
from .body_output import write_bodies
from .interface import PATCH_DEFECT_LIMIT  # noqa: F401 (`mixvi solve` reads it here)

# a bilateral interface of two bodies that stands apart by more than this fraction of the
# largest displacement of the slave's contact nodes is warned of: closing it changes the answer
CLOSED_GAP_TOL = 0.1


def closed_gap_summary(model: Any, sol: Solution) -> dict:
    """summary.json's contact.initial_gap_closed (bilateral contact of two bodies): the largest
    initial gap (m) the law closes, and that gap over the largest displacement of the slave's
    contact nodes; {} for unilateral contact and a rigid foundation."""
    c = model.contact
    if c.law != "bilateral" or c.master is None:
        return {}
    u = model.full(sol.u)[c.slave.u_dofs(c.tr.nodes)]  # (N, 2)
    scale = float(np.linalg.norm(u, axis=1).max(initial=0.0))
    ratio = c.closed_gap / scale if scale > 0 else (0.0 if c.closed_gap == 0 else np.inf)
    return {"initial_gap_closed": {"max": c.closed_gap, "relative_to_displacement": ratio}}


def closed_gap_warning(model: Any, sol: Solution) -> list[str]:
    """A warning when bilateral contact closes an initial gap above CLOSED_GAP_TOL × the
    largest contact displacement (a real gap, not rounding: use law = "unilateral")."""
    entry = closed_gap_summary(model, sol).get("initial_gap_closed")
    if entry is None or entry["relative_to_displacement"] <= CLOSED_GAP_TOL:
        return []
    return [
        f"contact: the bodies start apart by up to {entry['max']:.3g} m "
        f"({entry['relative_to_displacement']:.3g} × the largest contact displacement) and "
        "the bilateral law closes that gap; if the gap is real, set contact.law = "
        "'unilateral' (contact.initial_gap_closed)"
    ]


def contact_table(model: Any, sol: Solution) -> ContactTable:
    """One row per slave node of Γ3 (problems.output.results): λ_n, λ_t, the tangential
    mortar jump, the friction radius g and stick/slip; NaN and state 'no_multiplier' where a
    node carries none."""
    c = model.contact
    tr = c.tr
    st = model.contact_state(sol)
    k = tr.size
    lam_n, lam_t, jump_t, g = (np.full(k, np.nan) for _ in range(4))
    lam_n[c.rows_n] = st["lam_n"]
    lam_t[c.rows_t] = st["lam_t"]
    jump_t[c.rows_t] = st["jump_t"]
    g[c.rows_t] = st["g"]
    state = np.full(k, "no_multiplier", dtype=object)
    state[c.rows_t] = st["state"]
    gap = None
    if c.law == "unilateral":
        gap = np.full(k, np.nan)
        gap[c.rows_n] = np.maximum(st["gap"] - st["u_n"], 0.0)
    return ContactTable(
        points=c.slave.mesh.points[tr.nodes],
        normals=tr.normals,
        weights=tr.weights,
        segments=tr.facets,
        lambda_n=lam_n,
        lambda_t=lam_t,
        jump_t=jump_t,
        state=state.astype(str),
        gap=gap,
        friction=c.friction,
        bound=g,
    )


def postprocess(model: Any, sol: Solution, outdir: Path) -> dict:
    """Write VTU fields (one per body, the contact line), contact.csv and PNG plots
    into `outdir`; return the summary entries."""
    x_full = model.full(sol.u)
    files, notes = write_bodies(model, x_full, outdir)
    summary: dict = {"force_balance": piezo_balance.force_balance(model, sol)}
    if model.contact is not None:
        quad = piezo_balance.lemma_4_2(model, sol) if model.slip_origin is None else None
        if quad is not None:
            summary["lemma_4_2_quadrature"] = quad
        state = model.contact_state(sol)
        files += plots.contact_plots(state, outdir, title=model.scene.name)
        table = contact_table(model, sol)
        files += results.write_contact(outdir, table)[0]
        labels = state["state"]
        summary["contact"] = {
            "nodes": int(labels.size),
            "stick": int(np.sum(labels == "stick")),
            "slip": int(np.sum(labels == "slip")),
            "ambiguous": int(np.sum(labels == "ambiguous")),
            **(
                interface.unilateral_summary(
                    model.contact,
                    np.sum(state["normal_state"] == "open"),
                    state["gap"] - state["u_n"],
                )
                if model.contact.law != "bilateral"
                else {}
            ),
            **table.totals(),
            **interface.interface_summary(model.contact),
            **closed_gap_summary(model, sol),
            "table": table.records(),
        }
        summary["lemma_4_2"] = state["lemma_4_2"]
        if model.electrical is not None:
            summary["electrical"] = {
                **electrical_contact.report(model.electrical, sol),
                **electrical_contact.touching(model.electrical, sol, state["touch"]),
            }
        summary["warnings"] = interface.friction_warnings(
            state["state"], state["g"], state["lam_t"], state["slip"], state["touch"]
        ) + closed_gap_warning(model, sol)
    if notes:
        summary["notes"] = notes
    along = model.options.get("potential_along")
    if along is not None:
        b = next(bb for bb in model.bodies if bb.name == along[0])
        tr = trace(b.mesh, along[1])
        _, phi = b.split(x_full[b.offset : b.offset + b.size])
        files.append(
            plots.potential_plot(
                b.mesh.points[tr.nodes], tr.s, phi[tr.nodes], outdir, f"{along[0]}.{along[1]}"
            )
        )
    summary["files"] = sorted(files)
    return summary


def step_output(model: Any, sol: Solution, outdir: Path) -> dict:
    """One load step's files (no plots): a VTU per body, contact.vtu and contact.csv; the
    summary entries "files" and "contact" (the counts per state)."""
    files, _ = write_bodies(model, model.full(sol.u), outdir)
    out: dict = {"files": files}
    if model.contact is not None:
        table = contact_table(model, sol)
        written, contact = results.write_contact(outdir, table)
        files += written
        out["contact"] = contact["counts"]
    return out
