"""Result files of the 3D contact plug-in (docs/fem3d.md, "Contact: results").

- `BODY.vtu`: point data displacement (m, 3 components), electric_potential (V); cell data at
  the centroids: stress (Pa, symmetric tensor in VTK order XX, YY, ZZ, XY, YZ, XZ), von_mises
  (Pa), electric_field = −∇φ (V/m), electric_displacement (C/m²).
- `contact.vtu`: the slave contact surface (its quadrilaterals or triangles) with point data
  normal, tangent1, tangent2, lambda_n, lambda_t (along t1), lambda_t2, jump_t, jump_t2 (the
  names of contact.csv and of the 2D contact.vtu), lambda_t_vec and jump_t_vec (the tangential
  multiplier and jump as 3-vectors), g, state (index into STATES) and is_STATE (0/1).
- `contact.csv`: one row per surface node, `#` lines with units and meanings, written as the
  2D front's (`results.ContactTable`, `contact_table`); columns x, y, z, normal_*, tangent1_*,
  tangent2_*, lambda_n, lambda_t (along t1), lambda_t2, jump_t, jump_t2, g, gap (unilateral
  only), state.
- `contact_map.png`: the stick/slip map on the contact surface and |λ_t|/g.
(`mixvi solve` collects the .vtu files into `results.pvd`.)
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from fem.facets import frames
from problems.output.results import BOUNDS, ContactTable, write_contact_csv

from . import interface
from .body_output import write_bodies

# "ambiguous" (vi_core.states: not settled at the achieved residual) is the last code, so the
# others keep theirs
STATES = ("stick", "slip", "normal_only", "open", "no_multiplier", "ambiguous")
# the 3D state line of contact.csv (normal_only: a node whose tangents are prescribed)
STATE_MEANING = (
    "stick (|lambda_t| < {bound}), slip (|lambda_t| = {bound}), normal_only (tangents "
    "prescribed), open (not touching; unilateral only), no_multiplier (clamped node), "
    "ambiguous (not settled at the achieved residual: neither the stress margin nor the "
    "gap/slip decides it; solve with a smaller --tol)"
)


def contact_table(model, st: dict) -> ContactTable:
    """contact.csv's rows, one per surface node, in the 2D front's columns
    (`results.ContactTable`): the frame as tangent1_*, tangent2_*, λ_t and the tangential jump
    along t1, t2 (lambda_t, lambda_t2, jump_t, jump_t2), g, the remaining gap (unilateral)."""
    c = model.contact
    gap = np.maximum(st["gap"], 0.0) if c.law == "unilateral" else None  # NaN stays NaN
    bound = BOUNDS[c.friction]
    return ContactTable(
        points=c.slave.mesh.points[c.tr.nodes],
        normals=c.normals,
        weights=c.W,
        segments=c.tr.facets,
        lambda_n=st["lam_n"],
        lambda_t=np.stack([st["lam_t1"], st["lam_t2"]], axis=1),  # (k, 2)
        jump_t=np.stack([st["jump_t1"], st["jump_t2"]], axis=1),  # (k, 2)
        state=st["state"],
        gap=gap,
        tangents=np.stack([c.t1, c.t2], axis=1),  # (k, 2, 3)
        meanings={"state": STATE_MEANING.replace("{bound}", bound)},
        friction=c.friction,
        bound=st["g"],
    )


def write_surface_vtu(path: Path, model, st: dict) -> None:
    """The contact surface with the contact quantities as point data."""
    import meshio

    c = model.contact
    code = np.array([STATES.index(s) for s in st["state"]], dtype=np.int32)
    cols = contact_table(model, st).columns
    point = {
        **{k: v for k, v in cols.items() if k.startswith(("lambda", "jump")) or k == "g"},
        **{"normal": c.normals, "tangent1": c.t1, "tangent2": c.t2},
        **{"lambda_t_vec": st["lam_t_vec"], "jump_t_vec": st["jump_t_vec"], "state": code},
        **{f"is_{s}": (code == i).astype(np.int32) for i, s in enumerate(STATES)},
    }
    meshio.Mesh(
        c.slave.mesh.points[c.tr.nodes], [(c.tr.facet_type, c.tr.facets)], point_data=point
    ).write(str(path), file_format="vtu")


def chart(model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Plane coordinates (k, 2) of the contact surface nodes in the frame (a, b) of the mean
    normal, and a, b (3,)."""
    c = model.contact
    n = c.normals.sum(axis=0)
    a, b = frames(n[None, :] / np.linalg.norm(n))
    P = c.slave.mesh.points[c.tr.nodes]
    return np.stack([P @ a[0], P @ b[0]], axis=1), a[0], b[0]


def contact_map(path: Path, model, st: dict, title: str = "") -> None:
    """Two panels on the contact surface (seen along −n): the stick/slip state with the
    tangential traction −λ_t as arrows, and |λ_t|/g."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    from problems.output.plots import direction_label

    c = model.contact
    uv, a, b = chart(model)
    faces = c.tr.facets
    tris = (
        faces if faces.shape[1] == 3 else np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])
    )
    tri = Triangulation(uv[:, 0], uv[:, 1], tris)
    ratio = np.divide(
        np.linalg.norm(st["lam_t_vec"], axis=1),
        st["g"],
        out=np.zeros(c.tr.size),
        where=st["g"] > 0,
    )
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
        sel = st["state"] == s
        if sel.any():
            ax.scatter(uv[sel, 0], uv[sel, 1], s=14, color=col, label=f"{s} ({int(sel.sum())})")
    lt = -st["lam_t_vec"]  # the traction the foundation exerts on the slave
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
        axx.set_xlabel(direction_label(a))
        axx.set_ylabel(direction_label(b))
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def frame_checks(model) -> dict:
    """Orthonormality defect of the frames and the largest angle (degrees) between the t1 of
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


def write(model, sol, outdir: Path, contact_state: Callable) -> dict:
    """All result files of a solve; the summary entries."""
    files, _ = write_bodies(model, model.full(sol.u), outdir)
    summary: dict = {}
    if model.contact is not None:
        c = model.contact
        st = contact_state(model, sol)
        write_contact_csv(outdir / "contact.csv", contact_table(model, st))
        write_surface_vtu(outdir / "contact.vtu", model, st)
        contact_map(outdir / "contact_map.png", model, st, title=model.scene.name)
        files += ["contact.csv", "contact.vtu", "contact_map.png"]
        lam = np.nan_to_num(st["lam_n"])[:, None] * c.W_n[:, None] * c.normals
        force = -(lam + c.W_t[:, None] * st["lam_t_vec"]).sum(axis=0)  # -∫λ_h dA
        counts = {s: int((st["state"] == s).sum()) for s in STATES}
        summary["contact"] = {
            "nodes": int(st["has_t"].sum()),
            "stick": counts["stick"],
            "slip": counts["slip"],
            "ambiguous": counts["ambiguous"],
            "counts": counts,
            **{f"{s}_area": a for s, a in zip(STATES, areas(c, st), strict=True)},
            "force_on_slave": force.tolist(),
            "force_units": "N",
            **interface.interface_summary(c),
            "frames": frame_checks(model),
        }
        summary["lemma_4_2"] = st["lemma_4_2"]
        has_t = st["has_t"]
        summary["warnings"] = interface.friction_warnings(
            st["state"],
            st["g"][has_t],
            np.linalg.norm(st["lam_t_vec"][has_t], axis=1),
            st["slip"][has_t],
            st["touch"],
        )
        if c.law == "unilateral":
            open_nodes = np.sum(st["state"] == "open")
            summary["contact"] |= interface.unilateral_summary(c, open_nodes, st["gap"])
    summary["files"] = sorted(files)
    return summary


def areas(c, st: dict) -> list[float]:
    """The area of each of STATES: a node with rows counts with its class weight (W_t where it
    has a tangential row, W_n where a normal one only: ∫ψ̃_k dA, which under "merge" includes
    what its dropped neighbours gave it); no_multiplier gets the nodes without rows less what
    they gave away, so the areas add up to the surface's."""
    w = np.where(st["has_t"], c.W_t, c.W_n)  # (k,)
    state = st["state"]
    carried = state != "no_multiplier"
    given = 0.0 if c.ends == "keep" else float((w[carried] - c.W[carried]).sum())
    return [
        float(c.W[~carried].sum()) - given if s == "no_multiplier" else float(w[state == s].sum())
        for s in STATES
    ]
