"""What a contact interface tells the user, 2D and 3D alike: a trace node's name in error
texts and warnings (`node_at`), summary.json's interface and unilateral entries
(`interface_summary`, `unilateral_summary`) and the console warnings about the interface
(`interface_warnings`) and the friction bound of a solution (`friction_warnings`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fem.facets import Trace
from vi_core import states as node_states


def node_at(body: Any, tr: Trace, i: int) -> str:
    """'node 12 at [0.0, 1.0]' for trace index i of `body`'s contact boundary `tr`."""
    node = int(tr.nodes[i])
    return f"node {node} at {body.mesh.points[node].tolist()}"


def friction_warnings(
    states: np.ndarray, g: np.ndarray, lam_t: np.ndarray, slip: np.ndarray, touch: np.ndarray
) -> list[str]:
    """What a user must know about the friction bound of a solution: no node touching, g = 0,
    no node slipping (how much of the bound λ_t uses), and `vi_core.states.warnings`. `states`,
    `touch` per contact node; g (friction radius) and |λ_t| (both (k_t,)) and `slip` per node
    carrying a tangential multiplier."""
    if not touch.any():
        return ["no node of Γ3 touches: the bodies are apart (λ = 0)"]
    out = node_states.warnings(states)
    if not g.any():
        return [*out, "g = 0 on Γ3: frictionless sliding (a linear problem)"]
    if not slip.any():
        used = float(np.max(np.abs(lam_t) / np.where(g > 0, g, np.inf)))
        out.append(
            f"no node slips: the tangential multiplier uses at most {used:.3g} of the friction "
            "bound, so the problem is tied (g above every tangential stress)"
        )
    return out


def interface_summary(c: Any) -> dict:
    """summary.json's interface entries, 2D and 3D alike: the master, the mortar patch defect,
    the crosspoint basis, the multipliers per kind (2D: normal, tangential; 3D: normal, disc,
    line), the crosspoint nodes (covered nodes without every multiplier component) and the
    uncovered ones (no master behind their whole support: no multiplier)."""
    full_t = c.line if c.dim == 2 else c.disc  # the nodes with every tangential component
    dropped = np.setdiff1d(np.arange(c.tr.size), np.intersect1d(c.rows_n, full_t))
    dropped = np.setdiff1d(dropped, c.uncovered)
    kinds = (
        {"tangential": c.line.size} if c.dim == 2 else {"disc": c.disc.size, "line": c.line.size}
    )
    return {
        "master": "rigid" if c.master is None else c.master.name,
        "mortar_patch_defect": c.patch_defect,
        "ends": c.ends,
        "multipliers": {"normal": int(c.rows_n.size), **{k: int(v) for k, v in kinds.items()}},
        "crosspoint_nodes": c.tr.nodes[dropped].tolist(),
        "uncovered_nodes": c.tr.nodes[c.uncovered].tolist(),
    }


PATCH_DEFECT_LIMIT = 1e-8  # above it `mixvi solve` warns and exits 1 (unless --allow-defect)


def interface_warnings(contact: Any) -> list[str]:
    """Console warnings about the interface: uncovered slave nodes and the patch defect."""
    out = []
    tr = contact.tr
    if contact.uncovered.size:
        where = ", ".join(node_at(contact.slave, tr, int(i)) for i in contact.uncovered[:6])
        more = f" and {contact.uncovered.size - 6} more" if contact.uncovered.size > 6 else ""
        out.append(
            f"contact: {contact.uncovered.size} slave node(s) of {contact.slave.name}."
            f"{contact.slave_part} have no master behind their whole support and carry no "
            f"multiplier (left free): {where}{more}"
        )
    if contact.patch_defect > PATCH_DEFECT_LIMIT:
        out.append(
            f"contact: mortar patch defect {contact.patch_defect:.3g} > {PATCH_DEFECT_LIMIT:g}: "
            "a rigid translation of both bodies is not transferred across the interface — the "
            "mortar projection is wrong for this geometry; results are not trustworthy"
        )
    return out


def unilateral_summary(contact: Any, open_nodes: int, remaining: np.ndarray) -> dict:
    """summary.json's contact entries only unilateral contact has, 2D and 3D alike: the law,
    the friction, the number of open nodes and the smallest remaining gap (`remaining` per
    node or normal row, NaN where a node has none)."""
    return {
        "law": contact.law,
        "friction": contact.friction,
        "open": int(open_nodes),
        "min_gap": float(np.nanmin(remaining, initial=np.inf)),
    }
