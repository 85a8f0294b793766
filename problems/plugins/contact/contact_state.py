"""The contact state of a solution, 2D and 3D alike (`contact_state`): per trace node the
multipliers, jumps, friction radius and states (`vi_core.states`: multiplier margin and
gap/slip, thresholds scaled by the achieved residual), and the Lemma 4.2 identity
λᵀ(B u − gap₀) = Σ_k ρ_k W_t,k |[u]_t,k| ([u]_t since the previous load step on a load path:
`model.incremental`; relative to the larger of Σρ W|[u]_t| and, unilateral, the pressure
scale times Σ|B u − gap₀|; the pressure scale and what the state thresholds are relative to:
`jumps`). A 2D node is a 3D line node, so one computation serves both; only the layout of the
returned dict differs (per trace node in 3D, per row in 2D: `_per_row`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from vi_core import Solution
from vi_core import states as node_states


@dataclass
class Jumps:
    """The dimension-free part of a contact state (`jumps`).

    x_full (n_full,) the full solution; Bu (m,) B_full x, the weighted jumps in B_full's row
    order; Bi (m,) the same since the load path's previous step (`model.incremental`; Bu
    without one); gap_rows (m,) the initial gap on the normal rows (unilateral), 0 elsewhere;
    pressure the pressure scale (unilateral: the largest λ_n or the elastic nodal forces per
    smallest normal row weight, `jumps`; 0 for bilateral contact); th the state thresholds of
    `vi_core.states`.
    """

    x_full: np.ndarray
    Bu: np.ndarray
    Bi: np.ndarray
    gap_rows: np.ndarray
    pressure: float
    th: Any


def jumps(model: Any, sol: Solution, radius: np.ndarray) -> Jumps:
    """The `Jumps` of `sol`; radius the friction radius at λ (`contact.bound`). The states'
    thresholds scale with the achieved residual, the stress scale (the whole λ: with ρ ≪ λ_n a
    rounding shortfall of |λ_t| relative to λ is no stick evidence) and the displacement scale.

    The pressure scale (unilateral contact; 0 for bilateral) is the larger of the largest λ_n
    and the largest elastic nodal force |A u| over the displacement dofs turned into a
    pressure by the smallest weight W_n,k of a normal row, 2D and 3D alike. A state threshold
    decides whether a λ_n is zero, so it must be relative to the λ_n the forces could produce:
    λ_n is conjugate to the row (B u)_k = W_n,k [u]_n,k, so a nodal force f carried by row k is
    the pressure λ_n,k = f / W_n,k, and the largest is f / min_k W_n,k over the rows that carry
    a λ_n. It is the same quantity in any dimension (W_n,k a length in 2D, an area in 3D: the
    row sums of the normal class, `class_blocks`), and it ignores the weights of nodes without
    a normal row (clamped crosspoints, uncovered nodes), which no force can load as a λ_n. (3D
    once took the smallest nodal W of any trace node, those nodes included.)"""
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
        w_min = float(c.W_n[c.rows_n].min())  # the smallest normal row weight (docstring)
        force = float(np.abs(model.vi.matvec(sol.u)[disp]).max(initial=0.0)) / w_min
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


def contact_state(model: Any, sol: Solution) -> dict:
    """The contact state of `sol` on `model.contact` (module docstring).

    3D, per trace node (k): lam_n, lam_t1, lam_t2 (NaN where not carried), lam_t_vec (k, 3),
    jump_n, jump_t1, jump_t2 ((Bu)/W in the frame: the slave displacement for a rigid
    foundation, the mortar jump with a master), jump_t_vec, g (the friction radius of the
    solution: g; unilateral Tresca g where the node is not open, 0 elsewhere; Coulomb F·λ_n),
    has_t, gap (the remaining normal gap gap₀ − [u]_n, unilateral; NaN elsewhere), state
    (stick, slip, normal_only, open, ambiguous, no_multiplier), touch (touch evidence: every
    node with rows for bilateral contact), slip, pressure (the pressure scale: largest λ_n or
    the elastic stress).

    2D, per tangential row ("s", "points", "lam_t", "g", "jump_t", "ut_slave", "slip",
    "touch_t", "state" and "ut_master" with a master) and per normal row ("s_n", "lam_n",
    "touch", "normal_state" touch, open or ambiguous, and, unilateral only, "u_n" the normal
    jump [u]_n, "gap" the initial gap gap₀ and "pressure"); "friction" names the bound.
    """
    c = model.contact
    k = c.tr.size
    idx_n, idx_b, idx_l = c.rows()
    lam = sol.lam
    radius = c.bound(lam)  # (k,) the friction radius at λ
    rows_t = c.rows_t  # (N_t,) nodes with a tangential row
    j = jumps(model, sol, radius[rows_t])
    Bu, Bi, th = j.Bu, j.Bi, j.th  # (m,) each
    Wt = c.W_t  # (k,) the tangential rows' ∫ψ̃_k
    has_t = np.zeros(k, dtype=bool)
    has_t[rows_t] = True
    rows = has_t.copy()  # (k,) nodes carrying rows
    rows[c.rows_n] = True
    W_n = c.W_n[c.rows_n]  # (N_n,)
    u_n = Bu[idx_n] / W_n  # (N_n,) the normal (mortar) jump [u]_n
    gap0 = None if c.gap0 is None else c.gap0 / W_n  # (N_n,) the initial gap (unilateral)
    gap = np.full(k, np.nan)  # the remaining normal gap
    normal = np.full(k, "touch", dtype=object)  # bilateral: every node with rows touches
    if c.law == "unilateral":
        gap[c.rows_n] = gap0 - u_n
        normal[c.rows_n] = node_states.normal_states(lam[idx_n], gap[c.rows_n], th)
    ji = np.zeros((k, 2))  # the tangential jump (since the origin) in the node's frame
    ji[c.disc] = Bi[idx_b] / Wt[c.disc, None]
    ji[c.line, 0] = Bi[idx_l] / Wt[c.line]
    jt = np.linalg.norm(ji, axis=1)  # (k,) |[u]_t|
    d = c.dim
    vec, jvec = np.zeros((k, d)), np.zeros((k, d))  # λ_t and [u]_t as vectors
    lb, jb = lam[idx_b], Bu[idx_b] / Wt[c.disc, None]  # (N_b, 2) each
    if c.disc.size:
        vec[c.disc] = lb[:, :1] * c.t1[c.disc] + lb[:, 1:] * c.t2[c.disc]
        jvec[c.disc] = jb[:, :1] * c.t1[c.disc] + jb[:, 1:] * c.t2[c.disc]
    ll, jl = lam[idx_l], Bu[idx_l] / Wt[c.line]  # (N_l,) each
    vec[c.line] = ll[:, None] * c.line_dir
    jvec[c.line] = jl[:, None] * c.line_dir
    rho = radius * ((normal != "open") & rows)  # (k,) the friction radius; none where open
    tang = node_states.tangential_states(np.linalg.norm(vec, axis=1), rho, jt, th)
    state = np.full(k, "no_multiplier", dtype=object)
    state[rows] = node_states.node_states(normal, tang, has_t)[rows]
    g_abs = float(np.sum((rho * Wt * jt)[has_t]))
    lemma = lemma_4_2(lam, j, g_abs, float(np.sum((rho * Wt)[has_t])))
    if d == 2:
        return _per_row(c, lam, j, normal, rho, state, lemma, (u_n, gap0, jl))
    out = {
        key: np.full(k, np.nan)
        for key in ("lam_n", "lam_t1", "lam_t2", "jump_n", "jump_t1", "jump_t2")
    }
    out["lam_n"][c.rows_n] = lam[idx_n]
    out["jump_n"][c.rows_n] = u_n
    out["lam_t1"][c.disc], out["lam_t2"][c.disc] = lb[:, 0], lb[:, 1]
    out["jump_t1"][c.disc], out["jump_t2"][c.disc] = jb[:, 0], jb[:, 1]
    for slot, (lk, jk) in enumerate((("lam_t1", "jump_t1"), ("lam_t2", "jump_t2"))):
        sel = c.line_slot == slot
        out[lk][c.line[sel]] = ll[sel]
        out[jk][c.line[sel]] = jl[sel]
    return {
        **out,
        "lam_t_vec": vec,
        "jump_t_vec": jvec,
        "g": rho,
        "has_t": has_t,
        "touch": (normal == "touch") & rows,
        "gap": gap,
        "pressure": j.pressure,
        "slip": state == "slip",
        "state": state.astype(str),
        **lemma,
    }


def _per_row(
    c: Any,
    lam: np.ndarray,
    j: Jumps,
    normal: np.ndarray,
    rho: np.ndarray,
    state: np.ndarray,
    lemma: dict,
    jumps_rows: tuple[np.ndarray, np.ndarray | None, np.ndarray],
) -> dict:
    """The 2D layout of `contact_state`: per tangential row and per normal row; normal (k,),
    rho (k,) and state (k,) per node, lam the multiplier, j its `Jumps`, jumps_rows the normal
    jump [u]_n (N_n,), the initial gap (N_n,; None unless unilateral) and the tangential jump
    (N_t,) per row."""
    rows_t, rows_n = c.line, c.rows_n  # every tangential row of a 2D node is a line row
    u_n, gap0, jump_t = jumps_rows
    nodes = c.tr.nodes[rows_t]
    u_s = j.x_full[c.slave.u_dofs(nodes)]  # (N_t, 2)
    out = {
        "s": c.tr.s[rows_t],
        "points": c.slave.mesh.points[nodes],
        "s_n": c.tr.s[rows_n],
        "lam_n": c.normal(lam),
        "lam_t": c.tangential(lam),
        "g": rho[rows_t],
        "jump_t": jump_t,
        "ut_slave": np.einsum("ij,ij->i", u_s, c.t1[rows_t]),
        "slip": state[rows_t] == "slip",
        "state": state[rows_t],
        "touch": normal[rows_n] == "touch",
        "touch_t": normal[rows_t] == "touch",
        "normal_state": normal[rows_n],
        **lemma,
        "friction": c.friction,  # the bound's name in plots and tables (tresca: g, coulomb: Fλ_n)
    }
    if c.law == "unilateral":
        out["pressure"] = j.pressure  # the pressure scale
        out["u_n"] = u_n  # (N_n,) normal (mortar) jump [u]_n
        out["gap"] = gap0  # (N_n,) initial gap
    if c.master_proj is not None:
        out["ut_master"] = c.master_proj @ j.x_full
    return out
