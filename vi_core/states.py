"""Contact states that follow from the answer: one rule for every plug-in and solver.

A node's state (open, stick, slip) is decided from two kinds of evidence at once, each measured
against a threshold scaled by the achieved residual and the problem's own scales:

- normal: the multiplier λ_n (touch evidence) and the remaining gap (open evidence);
- tangential: the margin ρ − |λ_t| (stick evidence) and the slip |[u]_t| (slip evidence).

A node with evidence for exactly one side gets that side; with evidence for both or for neither
(a node at the flip, or a solve not accurate enough to tell) it is "ambiguous". Nothing here is
a fixed 1e-9: the thresholds are `factor · max(residual, eps) · scale`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .problem import MixedVI
    from .solution import Solution

#: how far beyond the achieved residual a piece of evidence must stand to count
FACTOR = 100.0
_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Thresholds:
    """Evidence thresholds: `lam` for multipliers (stresses), `u` for jumps (lengths)."""

    lam: float
    u: float


def thresholds(residual: float, lam_scale: float, u_scale: float) -> Thresholds:
    """Thresholds `FACTOR · max(residual, 16 eps) · scale` for stresses and lengths.

    residual : the solve's achieved relative residual; lam_scale : the stress scale (largest
    multiplier, friction radius or elastic stress); u_scale : the length scale (largest
    displacement or jump)."""
    r = FACTOR * max(float(residual), 16 * _EPS)
    return Thresholds(r * max(float(lam_scale), 1e-300), r * max(float(u_scale), 1e-300))


def solution_thresholds(sol: Solution, lam_scale: float, u_scale: float) -> Thresholds:
    """`thresholds` at the larger of the solution's achieved residual and the relative accuracy
    of (u, λ) its solver records beyond the residual (`info["states"]["accuracy"]`: the
    relative tolerance of an iterative linear solve that gave the last step), the stress
    threshold raised to FACTOR times the accuracy of λ its solver records
    (`info["states"]["lam_accuracy"]`: the fixed point's last change of the bound).

    Why the accuracy: the residual is a backward error; the labels read forward quantities
    (|[u]_t|, the margin ρ − |λ_t|). A direct solve's last step is exact to rounding, so its
    u and λ are accurate to about the residual; a step solved by GMRES to a relative
    residual rtol is accurate only to about rtol, which may stand far above the residual it
    reaches (hertz level 0 on the petsc engine's amg path, a KSP made per Newton step: residual
    2.6e-14, u within 4e-12 of the direct solve's, and the slip of the node on the symmetry
    axis, 0 exactly, read 1.8e-14 against a threshold of 1.6e-14: "slip" where the direct
    solve says "ambiguous")."""
    info = sol.info.get("states") or {}
    th = thresholds(max(sol.residual, float(info.get("accuracy", 0.0))), lam_scale, u_scale)
    acc = float(info.get("lam_accuracy", 0.0))
    return Thresholds(max(th.lam, FACTOR * acc), th.u)


def normal_states(lam_n: np.ndarray, gap: np.ndarray | None, th: Thresholds) -> np.ndarray:
    """Per normal node (k,): "touch", "open" or "ambiguous".

    lam_n (k,) : normal multipliers (compressive positive); gap (k,) : the remaining gap
    (gap₀ − [u]_n), or None for bilateral contact (every node touches)."""
    lam_n = np.asarray(lam_n, dtype=float)
    if gap is None:
        return np.full(lam_n.size, "touch", dtype=object)
    press = lam_n > th.lam  # (k,) touch evidence
    apart = np.asarray(gap, dtype=float) > th.u  # (k,) open evidence
    out = np.full(lam_n.size, "ambiguous", dtype=object)
    out[press & ~apart] = "touch"
    out[apart & ~press] = "open"
    return out


def tangential_states(
    lam_t: np.ndarray, rho: np.ndarray, slip: np.ndarray, th: Thresholds
) -> np.ndarray:
    """Per touching node (k,): "stick", "slip" or "ambiguous".

    lam_t (k,) : |λ_t| (the tangential multiplier's magnitude); rho (k,) : the friction radius
    (g, or F·λ_n); slip (k,) : |[u]_t| since the slip origin."""
    margin = np.asarray(rho, dtype=float) - np.abs(np.asarray(lam_t, dtype=float))  # (k,)
    held = margin > th.lam  # (k,) stick evidence: strictly inside the friction disc
    moved = np.abs(np.asarray(slip, dtype=float)) > th.u  # (k,) slip evidence
    out = np.full(margin.size, "ambiguous", dtype=object)
    out[held & ~moved] = "stick"
    out[moved & ~held] = "slip"
    return out


def node_states(
    normal: np.ndarray, tangential: np.ndarray | None, has_t: np.ndarray | None = None
) -> np.ndarray:
    """Combine per-node normal and tangential states (k,) into one label per node.

    open nodes are "open" whatever their tangential evidence; ambiguous normal evidence is
    "ambiguous"; touching nodes take their tangential state, or "normal_only" where the node
    carries no tangential rows (`has_t` False)."""
    out = np.asarray(normal, dtype=object).copy()
    touch = out == "touch"
    if tangential is None:
        out[touch] = "normal_only"
        return out
    tang = np.asarray(tangential, dtype=object)
    ht = np.ones(out.size, dtype=bool) if has_t is None else np.asarray(has_t, dtype=bool)
    out[touch & ht] = tang[touch & ht]
    out[touch & ~ht] = "normal_only"
    return out


def counts(states: np.ndarray) -> dict[str, int]:
    """Number of nodes per state label."""
    labels, n = np.unique(np.asarray(states, dtype=str), return_counts=True)
    return {str(k): int(v) for k, v in zip(labels, n, strict=True)}


def vi_states(
    vi: MixedVI, u: np.ndarray, lam: np.ndarray, residual: float, lam_accuracy: float = 0.0
) -> np.ndarray:
    """The states (k_total,) of (u, λ) at the nodes of `vi`'s contact blocks
    (`vi_core.coulomb.ContactSet`, block after block), by the same rule on the VI's own
    quantities — for a solver that must confirm its partition (the fixed point), where the
    plug-in's weights are unknown.

    Per node: λ_n and the gap gap_n − (B u)_n (touch/open), |λ_t| against the radius
    `tresca_bound(λ_n)` and the slip |(B u − gap)_t| (stick/slip). A mortar row of B is W_k
    times the nodal jump, so each row is divided by its weight ‖B_row‖₁ (W_k up to a factor
    between 1 and 2√dim: the normal's components, a master's row). Thresholds: the achieved
    `residual`, the stress scale max(|λ|, radius) (where nothing presses: |A u| on the
    displacement per smallest weight) and the displacement scale max |u| (the "displacement"
    field of `vi.fields` if named, else all of u). `lam_accuracy`: an accuracy of λ the solver
    knows beyond its residual (the fixed point: the last step's change of the bound); the
    stress threshold is at least FACTOR times it."""
    from .coulomb import ContactSet

    u, lam = np.asarray(u, dtype=float), np.asarray(lam, dtype=float)
    weight = _row_weights(vi.B)  # (m,)
    z = (vi.B @ u - vi.gap) / np.where(weight > 0, weight, 1.0)  # (m,) the rows' nodal jumps
    disp = (vi.fields or {}).get("displacement", slice(None))
    parts = []
    for block, sl in zip(vi.Lambda.blocks(), vi.Lambda.slices(), strict=True):
        if isinstance(block, ContactSet):
            lam_n, lam_t = block.split(lam[sl])
            z_n, z_t = block.split(z[sl])
            parts.append((block, lam_n, np.linalg.norm(lam_t, axis=1), -z_n, z_t, weight[sl]))
    if not parts:
        return np.array([], dtype=object)
    radius = [b.tresca_bound(ln) for b, ln, *_ in parts]
    lam_scale = max(
        float(np.abs(lam).max(initial=0.0)), max(float(r.max(initial=0.0)) for r in radius)
    )
    if lam_scale == 0.0:  # nothing presses: the elastic force per weight is the scale
        w_min = min(float(w[w > 0].min(initial=np.inf)) for *_, w in parts)
        lam_scale = float(np.abs(vi.matvec(u)[disp]).max(initial=0.0)) / min(w_min, 1.0)
    th = thresholds(residual, lam_scale, float(np.abs(u[disp]).max(initial=0.0)))
    th = Thresholds(max(th.lam, FACTOR * float(lam_accuracy)), th.u)
    out = []
    for (_, lam_n, lam_t, gap, z_t, _), r in zip(parts, radius, strict=True):
        normal = normal_states(lam_n, gap, th)
        rho = r * (normal != "open")  # (k,) no friction where open
        tang = tangential_states(lam_t, rho, np.linalg.norm(z_t, axis=1), th)
        out.append(node_states(normal, tang))
    return np.concatenate(out)


def _row_weights(B) -> np.ndarray:
    """(m,) ‖B_row‖₁: a mortar row's weight W_k up to a factor of order 1 (`vi_states`)."""
    return np.asarray(abs(B).sum(axis=1)).ravel()


def warnings(states: np.ndarray) -> list[str]:
    """The user's warning about ambiguous nodes among `states` (k,), or none."""
    n = int(np.sum(np.asarray(states, dtype=object) == "ambiguous"))
    if not n:
        return []
    return [
        f"{n} contact node(s) ambiguous: at the achieved residual neither the stress margin "
        "nor the gap/slip settles their state; solve with a smaller --tol to decide"
    ]


def compare(a: np.ndarray, b: np.ndarray) -> dict:
    """Partition agreement per node between two state arrays (k,) of the same nodes.

    A node ambiguous on either side is not a disagreement but is counted ("ambiguous"); any
    other differing label is ("disagree", with the node indices in "nodes")."""
    a, b = np.asarray(a, dtype=object), np.asarray(b, dtype=object)
    if a.shape != b.shape:
        raise ValueError(f"state arrays differ in shape: {a.shape} and {b.shape}")
    amb = (a == "ambiguous") | (b == "ambiguous")  # (k,)
    bad = ~amb & (a != b)  # (k,)
    return {
        "nodes": int(a.size),
        "agree": int(np.sum(~amb & ~bad)),
        "ambiguous": int(np.sum(amb)),
        "disagree": int(np.sum(bad)),
        "disagree_nodes": [int(i) for i in np.flatnonzero(bad)],
    }
