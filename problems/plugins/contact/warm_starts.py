"""Nested iteration's warm starts of the contact plug-in: a coarse level's solution carried to
the next finer level as the initial guess (λ0 from the coarse multipliers, u0 by
`transfer.carried_start`), along the contact curve in 2D (`along_curve`) and over the contact
surface in 3D (`over_surface`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from vi_core import Solution

from .. import transfer
from .output import chart


def along_curve(coarse: Any, coarse_sol: Solution, fine: Any) -> dict:
    """2D: the initial guess for `fine` from the solution on the coarser level.

    Along Γ3 (the same curve on every level, parametrised by normalised arc length) the normal
    coefficients are interpolated, and the tangential ones through their ratio r = α/ρ to the
    friction radius ρ (g; Coulomb: F·λ_n): a fine node between two coarse slip nodes gets
    |r| = 1, i.e. it starts on the bound even where g varies, and the first Newton step starts
    from the coarse stick/slip partition instead of rediscovering it. A fine node between a
    coarse stick and a coarse slip node starts on the bound where |r| extrapolated from the
    stick side reaches 1 (`_slip_ahead`).

    u0, the displacement and potential, is the coarse solution interpolated at the fine nodes
    (`transfer.prolongate`: the Q1/P1 prolongation of nested meshes; the new nodes of a curved
    boundary lie outside the coarse mesh and are extrapolated, counted in
    start["outside_nodes"]), then tied where λ0 predicts a tied row (`vi_core.ssn.tied_start`):
    the first Newton step's GMRES starts from it (paper scene, levels 2–5: 12, 13, 15, 16
    iterations instead of 14, 15, 18, 19 from u = 0).
    """
    if coarse.contact is None or fine.contact is None:
        return {}
    cc, fc = coarse.contact, fine.contact
    sc, sf = cc.tr.s / cc.tr.s[-1], fc.tr.s / fc.tr.s[-1]
    lam_c = coarse_sol.lam
    lam_n = np.interp(sf[fc.rows_n], sc[cc.rows_n], cc.normal(lam_c))
    rc = cc.bound(lam_c)[cc.rows_t]  # (N_t,)
    ratio_c = np.divide(cc.tangential(lam_c), rc, out=np.zeros(rc.size), where=rc > 0)
    ratio = np.clip(np.interp(sf[fc.rows_t], sc[cc.rows_t], ratio_c), -1.0, 1.0)
    on_bound = (np.abs(ratio) >= 1.0 - transfer.ON_BOUND) | _slip_ahead(
        sc[cc.rows_t], ratio_c, sf[fc.rows_t]
    )
    ratio[on_bound] = np.sign(ratio[on_bound])
    lam0 = np.zeros(fc.B_full.shape[0])
    lam0[fc.idx_n] = lam_n
    lam0[fc.idx_t] = ratio * fc.bound(lam0)[fc.rows_t]
    return transfer.carried_start(coarse, coarse_sol, fine, lam0)


def _slip_ahead(xc: np.ndarray, ratio_c: np.ndarray, xf: np.ndarray) -> np.ndarray:
    """(M,) fine positions xf (M,) lying between a coarse stick node a and a coarse slip node
    (coarse positions xc (K,) increasing, ratios α/ρ `ratio_c` (K,)) where |r| extrapolated
    linearly from a and its other neighbour b (also stick) reaches 1.

    Why: the ratio rises steeply towards a stick/slip transition, so interpolating it between a
    and the slip node leaves the new node between them below 1 (stick) where the fine solution
    slips. Paper scene, nested iteration: levels 4 and 5 found the new nodes next to both
    transitions slipping (|r_a| = 0.937, |r_b| = 0.709 at level 3: extrapolated 1.05 at the
    midpoint; 0.934, 0.784 at level 4: 1.009), which took the fine level a second Newton step
    with its own linear solve; at levels 2 and 3 extrapolation gives 0.84 and 0.61: stick, as
    the fine solutions have it."""
    slip = np.abs(ratio_c) >= 1.0 - transfer.ON_BOUND  # (K,)
    out = np.zeros(xf.size, dtype=bool)
    if xc.size < 3:
        return out
    k = np.clip(np.searchsorted(xc, xf, side="right") - 1, 0, xc.size - 2)  # (M,) interval
    edge = slip[k] != slip[k + 1]  # (M,) between a stick and a slip node
    a = np.where(slip[k], k + 1, k)  # (M,) its stick end
    b = np.where(slip[k], k + 2, k - 1)  # (M,) the stick end's other neighbour
    ok = edge & (b >= 0) & (b < xc.size) & (xf > xc[k]) & (xf < xc[k + 1])
    a, b = a[ok], b[ok]
    ok_b = ~slip[b]
    ra, rb = np.abs(ratio_c[a]), np.abs(ratio_c[b])
    r = ra + (ra - rb) * (xf[ok] - xc[a]) / (xc[a] - xc[b])  # linear through b and a
    out[np.flatnonzero(ok)[ok_b & (r >= 1.0)]] = True
    return out


def over_surface(contact_state: Callable, coarse: Any, coarse_sol: Solution, fine: Any) -> dict:
    """3D: the initial guess for `fine` from the coarser level's solution (`contact_state`:
    the 3D front's).

    λ0: λ_n and the friction ratio r = λ_t/ρ (ρ the friction radius) interpolated linearly
    over the contact surface, |r| and the direction of r separately (then in the fine frames,
    clipped to |r| ≤ 1 and put on the bound where it reaches it), so a fine node between
    coarse slip nodes starts slipping: interpolating the vector r shortens it wherever the
    slip direction turns (bracket3d level 1: 25 of the 71 slip nodes predicted, 78 with 67
    right this way).

    u0: the coarse displacement (and potential) at the fine nodes
    (`transfer.prolongate`; fine nodes outside the coarse mesh, extrapolated, are
    counted in start["outside_nodes"]), then moved on the slave dofs so that B u0 = gap on
    the rows λ0 predicts tied (normal rows that touch, stick nodes; `vi_core.ssn.tied_start`),
    every other row of B u0 kept. Why: the first Newton step decides stick or slip from
    y = λ0 + B u0 − gap, and with u0 = 0 a predicted slip node has |y_t| = ρ to rounding —
    the disc's boundary, counted as stick (`vi_core.Ball`): bracket3d level 2 took its first
    step with 73 of the 201 slip nodes free, then 8 Newton steps; the carried slip puts y
    outside the disc. The tied rows are given to `tied_start` for the same reason.
    """
    if coarse.contact is None or fine.contact is None:
        return {}
    from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator
    from scipy.spatial import QhullError

    cc, fc = coarse.contact, fine.contact
    st = contact_state(coarse, coarse_sol)
    uv_c, a, b = chart(coarse)  # (k_c, 2) chart coordinates
    uv_f = fc.slave.mesh.points[fc.tr.nodes] @ np.stack([a, b], axis=1)  # (k_f, 2)

    def interp(vals: np.ndarray, known: np.ndarray) -> np.ndarray:
        pts, v = uv_c[known], vals[known]
        try:
            out = LinearNDInterpolator(pts, v)(uv_f)
        except QhullError:  # fewer than 3 known points, or all on one line: nearest only
            return NearestNDInterpolator(pts, v)(uv_f)
        miss = np.isnan(out).any(axis=-1) if out.ndim > 1 else np.isnan(out)
        if miss.any():
            out[miss] = NearestNDInterpolator(pts, v)(uv_f[miss])
        return out

    lam_n_c = np.zeros(cc.tr.size)
    lam_n_c[cc.rows_n] = st["lam_n"][cc.rows_n]
    lam_n = interp(lam_n_c, np.isin(np.arange(cc.tr.size), cc.rows_n))[fc.rows_n]
    has_t = np.isin(np.arange(cc.tr.size), np.concatenate([cc.disc, cc.line]))
    rho = st["g"]  # (k_c,) the friction radius of the coarse solution
    ratio_c = np.divide(
        st["lam_t_vec"], rho[:, None], out=np.zeros((cc.tr.size, 3)), where=rho[:, None] > 0
    )
    mag = interp(np.linalg.norm(ratio_c, axis=1), has_t)  # (k_f,) |r|
    r = interp(ratio_c, has_t)  # (k_f, 3) its direction
    length = np.linalg.norm(r, axis=1)  # (k_f,)
    r *= np.divide(mag, length, out=np.zeros_like(mag), where=length > 0)[:, None]
    r1 = np.einsum("ij,ij->i", r, fc.t1)
    r2 = np.einsum("ij,ij->i", r, fc.t2)
    rd = np.stack([r1[fc.disc], r2[fc.disc]], axis=1)  # (N_b, 2)
    norm = np.linalg.norm(rd, axis=1)
    slip_b = norm >= 1.0 - transfer.ON_BOUND  # (N_b,)
    rd = np.where(slip_b[:, None], rd / np.maximum(norm, 1e-300)[:, None], rd)
    rl = np.clip(np.einsum("ij,ij->i", r[fc.line], fc.line_dir), -1.0, 1.0)
    slip_l = np.abs(rl) >= 1.0 - transfer.ON_BOUND  # (N_l,)
    rl = np.where(slip_l, np.sign(rl), rl)
    idx_n, idx_b, idx_l = fc.rows()
    lam0 = np.zeros(fc.B_full.shape[0])
    lam0[idx_n] = lam_n
    bound = fc.bound(lam0)  # (k_f,) the fine radius at the interpolated λ_n
    lam0[idx_b] = rd * bound[fc.disc, None]
    lam0[idx_l] = rl * bound[fc.line]
    tied = np.zeros(lam0.size, dtype=bool)  # (m,) the rows λ0 predicts tied
    tied[idx_n] = True if fc.law == "bilateral" else lam_n > 0
    tied[idx_b] = ((bound[fc.disc] > 0) & ~slip_b)[:, None]
    tied[idx_l] = (bound[fc.line] > 0) & ~slip_l
    return transfer.carried_start(coarse, coarse_sol, fine, lam0, tied)
