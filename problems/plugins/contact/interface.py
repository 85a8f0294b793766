"""What the 2D (`plane`) and 3D (`solid`) contact fronts share, written once: node names in
error texts, the checked friction-bound integrand, the rigid foundation's gap, the multiplier
rows handed to the mixed VI, the layout-free part of the contact state (jumps, pressure
scale, thresholds, Lemma 4.2) and the friction warnings. Each front keeps its rows (2D:
segment mortar, a normal and one tangential row per node; 3D: frames, polygon-clipping
mortar, discs and lines), its two-body gap (2D: distance along the slave normal; 3D: weighted
mortar gap) and the layout of its contact state (2D per multiplier row, 3D per surface node).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from fem.facets import Trace
from problems.errors import SceneError
from vi_core import Solution
from vi_core import states as node_states

# Quadrature order of the 3D contact surface integrals (W, normals, g_k, the dual basis of the
# mortar): Q1 faces of a curved surface are not planar and |∂x/∂ξ × ∂x/∂η| is not polynomial
# (order 4 leaves 7e-11 in the rigid-body rows of spherical_cap, order 8 3e-15); P1 faces are
# flat (order 4 exact).
SURFACE_ORDER = {"hexahedron": 8, "tetra": 4}


def node_at(body: Any, tr: Trace, i: int) -> str:
    """'node 12 at [0.0, 1.0]' for trace index i of `body`'s contact boundary `tr`."""
    node = int(tr.nodes[i])
    return f"node {node} at {body.mesh.points[node].tolist()}"


def checked_bound(fun: Any) -> Callable[..., np.ndarray]:
    """The friction bound g (Tresca) or coefficient F (Coulomb), an expression of the
    coordinates whose `path` ends in .g or .F, as an integrand that refuses a negative value
    at a quadrature point (SceneError naming the field)."""
    what = "a friction bound g" if fun.path.endswith(".g") else "a friction coefficient F"

    def checked(*x: np.ndarray) -> np.ndarray:
        v = fun(*x)
        if (v < 0).any():
            raise SceneError(fun.path, float(v.min()), f"{what} ≥ 0 everywhere on Γ3")
        return v

    return checked


def rigid_gap(gap: Any, points: np.ndarray) -> np.ndarray:
    """(k,) the scene's initial gap to a rigid foundation at the points (k, d); 0 without a
    `gap` field; SceneError where it is negative."""
    if gap is None:
        return np.zeros(points.shape[0])
    out = np.broadcast_to(np.asarray(gap(*points.T), float), points.shape[:1]).copy()
    if (out < 0).any():
        raise SceneError(gap.path, float(out.min()), "a distance ≥ 0 at every node of Γ3")
    return out


@dataclass
class Jumps:
    """The dimension-free part of a contact state (`jumps`).

    x_full (n_full,) the full solution; Bu (m,) B_full x, the weighted jumps in B_full's row
    order; Bi (m,) the same since the load path's previous step (`model.incremental`; Bu
    without one); gap_rows (m,) the initial gap on the normal rows (unilateral), 0 elsewhere;
    pressure the pressure scale (unilateral: the largest λ_n or the elastic nodal forces per
    `w_min`; 0 for bilateral contact); th the state thresholds of `vi_core.states`.
    """

    x_full: np.ndarray
    Bu: np.ndarray
    Bi: np.ndarray
    gap_rows: np.ndarray
    pressure: float
    th: Any


def jumps(model: Any, sol: Solution, radius: np.ndarray, w_min: Callable[[], float]) -> Jumps:
    """The `Jumps` of `sol`; radius the friction radius at λ (`contact.bound`), w_min() the
    area (length) by which the nodal forces become a pressure (asked for unilateral contact
    only). The states' thresholds scale with the achieved residual, the stress scale (the
    whole λ: with ρ ≪ λ_n a rounding shortfall of |λ_t| relative to λ is no stick evidence)
    and the displacement scale."""
    c = model.contact
    x_full = model.full(sol.u)
    Bu = c.B_full @ x_full  # (m,)
    gap_rows = np.zeros(Bu.size)
    pressure = 0.0
    disp = model.unknown_fields().get("displacement", slice(None))  # unnamed fields: all of u
    if c.law == "unilateral":
        gap_rows[c.idx_n] = c.gap0
        # the elastic nodal forces per area: the pressure scale when the bodies are apart (all
        # of λ is rounding then)
        force = float(np.abs((model.vi.A @ sol.u)[disp]).max(initial=0.0)) / w_min()
        pressure = max(float(sol.lam[c.idx_n].max(initial=0.0)), force)
    Bi = Bu if model.slip_origin is None else Bu - model.slip_origin  # slip since the origin
    th = node_states.solution_thresholds(
        sol,
        max(float(np.abs(sol.lam).max(initial=0.0)), float(radius.max(initial=0.0)), pressure),
        float(np.abs(sol.u[disp]).max(initial=0.0)),
    )
    return Jumps(x_full, Bu, Bi, gap_rows, pressure, th)


def lemma_4_2(lam: np.ndarray, j: Jumps, g_abs: float, weight: float) -> dict:
    """The Lemma 4.2 identity λᵀ(B u − gap₀) = Σ_k ρ_k W_k |[u]_t,k| of a solution: its two
    sides and the relative defect, relative to the larger of Σ ρ W |[u]_t| (`g_abs`) and the
    pressure scale times Σ|B u − gap₀| (unilateral), floored by rounding of Σ ρ W (`weight`)
    times the largest |x|."""
    b_uh_lam = float(lam @ (j.Bi - j.gap_rows))
    tiny = np.finfo(float).eps * weight * max(np.abs(j.x_full).max(), 1e-300)
    scale = max(g_abs, j.pressure * float(np.abs(j.Bi - j.gap_rows).sum()))
    return {
        "b_uh_lam": b_uh_lam,
        "int_g_abs_u": g_abs,
        "lemma_4_2": float(abs(b_uh_lam - g_abs) / max(scale, tiny, 1e-300)),
    }


def multiplier_rows(contact: Any) -> tuple:
    """(B_full (m, n_full), the gap rows not from Dirichlet data (m,): the initial gap on the
    normal rows, Λ_h, the Y Gram matrix (m, m): diag h_k w_r, a mesh-dependent H^{-1/2}
    stand-in) of a front's contact (`model.mixed_vi`); the front's contact tells its
    `Lambda()` and `gram_weights()`."""
    gap = np.zeros(contact.B_full.shape[0])  # (m,)
    if contact.gap0 is not None:
        gap[contact.idx_n] += contact.gap0
    return contact.B_full, gap, contact.Lambda(), sp.diags(contact.gram_weights())


def friction_radius(contact: Any, lam: np.ndarray, size: int, at: Any = slice(None)) -> np.ndarray:
    """The friction radius at the multiplier λ (B_full's row order) on the trace nodes `at` of
    the `size` nodes: g (bilateral), g where λ_n > 0 and 0 elsewhere (unilateral Tresca),
    F·max(λ_n, 0) (Coulomb); λ_n = 0 where a node carries no normal row; g, F are on `at`."""
    if contact.law == "bilateral":
        return contact.g
    lam_n = np.zeros(size)
    lam_n[contact.rows_n] = lam[contact.idx_n]
    lam_n = lam_n[at]
    if contact.friction == "coulomb":
        return contact.F * np.maximum(lam_n, 0.0)
    return contact.g * (lam_n > 0)


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
