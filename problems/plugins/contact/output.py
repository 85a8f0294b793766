"""Result files and summary entries of a contact solve, 2D and 3D alike (docs/design.md,
"Results"; docs/fem3d.md, "Contact: results"): one writer, dimension-specific only in its
figures and checks.

- `BODY.vtu` per body (`body_output.write_bodies`).
- `contact.csv` and `contact.vtu`: one row (point) per slave node of Γ3 (`contact_table`,
  `problems.output.results.ContactTable`): a 2D node is a 3D "line" node with one tangent, its
  multiplier rows mapped onto it (`node_view`). contact.vtu is the contact curve (2D) or surface
  (3D) with the table's columns, the normal and tangents, λ_t and [u]_t as vectors
  (lambda_t_vec, jump_t_vec), the state (index into `results.STATES`) and is_STATE (0/1).
- Figures: 2D the line plots contact_multiplier.png / contact_displacement.png (and the
  potential along a boundary, `[output] potential_along`); 3D the stick/slip map
  contact_map.png on the surface.
- summary.json's `contact` (counts, forces and measures per state from the table, the
  interface, the rows as `table`), `lemma_4_2`, `warnings`; 2D adds the independent force
  balance and Lemma 4.2 by quadrature (`balance`), the electrical contact and the initial gap a
  bilateral law closes; 3D the frame defects and `checks`.

The contact force −∫λ_h uses the class weights ∫ψ̃_k (W_n on λ_n, W_t on λ_t) in both
dimensions: λ_h = Σ_k λ_k ψ̃_k, so Σ_k λ_k ∫ψ̃_k is its integral, the resultant of the slave's
nodal contact forces −Bᵀλ (the row sums of a class's slave block are its W_c), and the force
the independent 2D balance integrates. Where the crosspoint rule "merge" hands a dropped node's
dual function to its neighbours, W_c exceeds the nodal ∫φ_k there; the nodal weights would
lose the dropped node's share. The length (2D) or area (3D) per state sums the nodal weights
∫φ_k (`ContactTable.totals`): they partition Γ3, the class weights do not.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fem.facets import frames, trace
from problems.output import plots, results
from problems.output.results import BOUNDS, ContactTable
from vi_core import Solution
from vi_core import states as node_states

from ..contract import triangles
from . import balance as piezo_balance
from . import checks, reports
from . import electrical as electrical_contact
from .body_output import write_bodies
from .contact_state import contact_state

# a bilateral interface of two bodies that stands apart by more than this fraction of the
# largest displacement of the slave's contact nodes is warned of: closing it changes the answer
CLOSED_GAP_TOL = 0.1
# the state line of contact.csv
STATE_MEANING = (
    "stick (|lambda_t| < {bound}), slip (|lambda_t| = {bound}), normal_only (tangents "
    "prescribed), open (not touching; unilateral only), no_multiplier (crosspoint, clamped or "
    "uncovered node), ambiguous (not settled at the achieved residual: neither the stress "
    "margin nor the gap/slip decides it; solve with a smaller --tol)"
)


def node_view(model: Any, st: dict) -> dict:
    """The contact state `st` (`contact_state`) per slave trace node (k), 2D and 3D alike:
    lam_n (k,), lam_t and jump_t (k, d − 1) along the frame's tangents, g (k,) the friction
    radius, has_t (k,) the node carries a tangential multiplier, state (k,), touch (k,), gap
    (k,) the remaining normal gap gap₀ − [u]_n (unilateral; else None); NaN where a node carries
    no such row (g: no tangential row). 2D's per-row layout is put onto its nodes; a node with a
    normal row only takes its normal state (touch: normal_only), as in 3D."""
    c = model.contact
    k = c.tr.size
    has_t = np.zeros(k, dtype=bool)
    has_t[c.rows_t] = True
    if c.dim == 3:
        lam_t = np.stack([st["lam_t1"], st["lam_t2"]], axis=1)  # (k, 2)
        jump_t = np.stack([st["jump_t1"], st["jump_t2"]], axis=1)  # (k, 2)
        out = {"lam_n": st["lam_n"], "state": st["state"], "touch": st["touch"]}
        out["gap"] = st["gap"] if c.law == "unilateral" else None
    else:
        rows_n, rows_t = c.rows_n, c.rows_t  # rows_t: the 2D tangential rows, in their order
        lam_t, jump_t = np.full((k, 1), np.nan), np.full((k, 1), np.nan)
        lam_t[rows_t, 0], jump_t[rows_t, 0] = st["lam_t"], st["jump_t"]
        state = np.full(k, "no_multiplier", dtype=object)
        state[rows_n] = node_states.node_states(st["normal_state"], None)  # normal row only
        state[rows_t] = st["state"]
        out = {"lam_n": np.full(k, np.nan), "state": state.astype(str), "touch": np.zeros(k, bool)}
        out["lam_n"][rows_n] = st["lam_n"]
        out["touch"][rows_n] = st["touch"]
        out["gap"] = None
        if c.law == "unilateral":
            out["gap"] = np.full(k, np.nan)
            out["gap"][rows_n] = st["gap"] - st["u_n"]
    g = np.full(k, np.nan)
    g[has_t] = st["g"] if c.dim == 2 else st["g"][has_t]
    return {**out, "lam_t": lam_t, "jump_t": jump_t, "g": g, "has_t": has_t}


def contact_table(model: Any, sol: Solution, st: dict | None = None) -> ContactTable:
    """contact.csv's rows, one per slave node of Γ3 (`node_view` of the contact state `st`,
    computed if not given): λ_n, λ_t and the tangential mortar jump along the tangents, the
    friction radius g, the remaining gap (unilateral), the state; the class weights W_n, W_t
    for the force. 2D writes its tangent τ = (−n_y, n_x) implicitly (no tangent columns), 3D
    the frame as tangent1_*, tangent2_*."""
    return _table(model, node_view(model, contact_state(model, sol) if st is None else st))


def _table(model: Any, nv: dict) -> ContactTable:
    """`contact_table` of the node view `nv` (`node_view`)."""
    c = model.contact
    return ContactTable(
        points=c.slave.mesh.points[c.tr.nodes],
        normals=c.normals,
        weights=c.W,
        segments=c.tr.facets,
        cell_type=c.tr.facet_type,
        lambda_n=nv["lam_n"],
        lambda_t=nv["lam_t"],
        jump_t=nv["jump_t"],
        state=nv["state"],
        gap=None if nv["gap"] is None else np.maximum(nv["gap"], 0.0),  # NaN stays NaN
        tangents=None if c.dim == 2 else np.stack([c.t1, c.t2], axis=1),  # (k, 2, 3)
        meanings={"state": STATE_MEANING.replace("{bound}", BOUNDS[c.friction])},
        friction=c.friction,
        bound=nv["g"],
        weights_n=c.W_n,
        weights_t=c.W_t,
    )


def closed_gap_summary(model: Any, sol: Solution) -> dict:
    """summary.json's contact.initial_gap_closed (bilateral contact of two bodies, 2D: the
    curve builder measures the gap): the largest initial gap (m) the law closes, and that gap
    over the largest displacement of the slave's contact nodes; {} otherwise."""
    c = model.contact
    if c.law != "bilateral" or c.master is None or c.dim != 2:
        return {}
    u = model.full(sol.u)[c.slave.u_dofs(c.tr.nodes)]  # (N, d)
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


def contact_summary(model: Any, sol: Solution, st: dict, nv: dict, table: ContactTable) -> dict:
    """summary.json's `contact`, `lemma_4_2` and `warnings` entries of the contact state `st`,
    its node view `nv` (`node_view`) and its `table`."""
    c = model.contact
    totals = table.totals()
    counts, has_t = totals["counts"], nv["has_t"]
    entry = {
        "nodes": int(has_t.sum()),
        **{s: counts[s] for s in ("stick", "slip", "ambiguous")},
        **(
            reports.unilateral_summary(c, counts["open"], nv["gap"])
            if c.law == "unilateral"
            else {}
        ),
        **totals,
        **reports.interface_summary(c),
        **closed_gap_summary(model, sol),
        **({"frames": frame_checks(model)} if c.dim == 3 else {}),
        "table": table.records(),
    }
    warnings = reports.friction_warnings(
        nv["state"],
        nv["g"][has_t],
        np.linalg.norm(table.vectors("lambda_t")[has_t], axis=1),
        nv["state"][has_t] == "slip",
        nv["touch"],
    )
    return {
        "contact": entry,
        "lemma_4_2": st["lemma_4_2"],
        "warnings": warnings + closed_gap_warning(model, sol),
    }


def postprocess(model: Any, sol: Solution, outdir: Path) -> dict:
    """Write the body VTUs, contact.csv, contact.vtu and the figures into `outdir`; return the
    summary entries (module docstring)."""
    x_full = model.full(sol.u)
    files, notes = write_bodies(model, x_full, outdir)
    c = model.contact
    summary: dict = {}
    if model.dimension == 2:
        summary["force_balance"] = piezo_balance.force_balance(model, sol)
        quad = (
            None
            if c is None or model.slip_origin is not None
            else (piezo_balance.lemma_4_2(model, sol))
        )
        if quad is not None:
            summary["lemma_4_2_quadrature"] = quad
    if c is not None:
        st = contact_state(model, sol)
        nv = node_view(model, st)
        table = _table(model, nv)
        files += results.write_contact(outdir, table)[0]
        if c.dim == 2:
            files += plots.contact_plots(st, outdir, title=model.scene.name)
        else:
            contact_map(outdir / "contact_map.png", model, table, title=model.scene.name)
            files.append("contact_map.png")
        summary |= contact_summary(model, sol, st, nv, table)
        electrical = getattr(model, "electrical", None)
        if electrical is not None:
            summary["electrical"] = {
                **electrical_contact.report(electrical, sol),
                **electrical_contact.touching(electrical, sol, st["touch"]),
            }
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
    if model.dimension == 3:
        summary["checks"] = checks.solution_checks(model, sol)
    return summary


def step_output(model: Any, sol: Solution, outdir: Path) -> dict:
    """One load step's files (no figures): a VTU per body, contact.vtu and contact.csv; the
    summary entries "files" and "contact" (the counts per state)."""
    files, _ = write_bodies(model, model.full(sol.u), outdir)
    out: dict = {"files": files}
    if model.contact is not None:
        written, contact = results.write_contact(outdir, contact_table(model, sol))
        files += written
        out["contact"] = contact["counts"]
    return out


def chart(model: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Plane coordinates (k, 2) of the 3D contact surface nodes in the frame (a, b) of the mean
    normal, and a, b (3,)."""
    c = model.contact
    n = c.normals.sum(axis=0)
    a, b = frames(n[None, :] / np.linalg.norm(n))
    P = c.slave.mesh.points[c.tr.nodes]
    return np.stack([P @ a[0], P @ b[0]], axis=1), a[0], b[0]


def contact_map(path: Path, model: Any, table: ContactTable, title: str = "") -> None:
    """Two panels on the 3D contact surface (seen along −n): the stick/slip state with the
    tangential traction −λ_t as arrows, and |λ_t|/g."""
    from matplotlib.tri import Triangulation

    plt = plots.pyplot()
    c = model.contact
    uv, a, b = chart(model)
    tri = Triangulation(uv[:, 0], uv[:, 1], triangles(c.tr.facets))
    lam_t = table.vectors("lambda_t")  # (k, 3)
    g = np.nan_to_num(table.bound)  # (k,)
    ratio = np.divide(np.linalg.norm(lam_t, axis=1), g, out=np.zeros(c.tr.size), where=g > 0)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    ax = axes[0]
    colors = {
        "stick": "tab:blue",
        "slip": "tab:red",
        "normal_only": "0.6",
        "no_multiplier": "k",
        "ambiguous": "tab:orange",
    }
    ax.triplot(tri, color="0.85", lw=0.4)
    for s, col in colors.items():
        sel = table.state == s
        if sel.any():
            ax.scatter(uv[sel, 0], uv[sel, 1], s=14, color=col, label=f"{s} ({int(sel.sum())})")
    lt = -lam_t  # the traction the foundation exerts on the slave
    ax.quiver(uv[:, 0], uv[:, 1], lt @ a, lt @ b, color="0.3", width=0.003)
    ax.set_title("stick/slip state, arrows: tangential traction $-\\lambda_t$")
    ax.legend(fontsize=7, loc="upper right")
    ax2 = axes[1]
    im = ax2.tripcolor(tri, ratio, shading="gouraud", vmin=0.0, vmax=1.0, cmap="viridis")
    ax2.tricontour(tri, ratio, levels=[1.0 - 1e-6], colors="r", linewidths=1.0)
    fig.colorbar(im, ax=ax2, label="$|\\lambda_t|/g$ (1: slip)")
    ax2.set_title("$|\\lambda_t|/g$")
    for axx in axes:
        axx.set_aspect("equal")
        axx.set_xlabel(plots.direction_label(a))
        axx.set_ylabel(plots.direction_label(b))
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def frame_checks(model: Any) -> dict:
    """Orthonormality defect of the 3D frames and the largest angle (degrees) between the t1 of
    two nodes sharing a face edge (small on a smooth surface: the frames are continuous)."""
    c = model.contact
    F = np.stack([c.t1, c.t2, c.normals], axis=1)  # (k, 3, 3)
    ortho = float(np.abs(F @ F.transpose(0, 2, 1) - np.eye(3)).max())
    hand = float(np.abs(np.cross(c.t1, c.t2) - c.normals).max())
    e = c.tr.edges()
    interior = np.isin(e, c.disc).all(axis=1)
    cosang = np.einsum("ij,ij->i", c.t1[e[interior, 0]], c.t1[e[interior, 1]])
    jump = float(np.degrees(np.arccos(np.clip(cosang, -1, 1))).max(initial=0.0))
    return {"orthonormality_defect": ortho, "handedness_defect": hand, "max_t1_turn_deg": jump}
