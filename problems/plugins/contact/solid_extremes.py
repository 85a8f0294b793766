"""The `mixvi extremes` rows of contact3d: the 3D scenes pushed to extreme friction bounds, data
scales, materials, poling directions, curved contact surfaces and near-incompressibility.

Each row's checks, on top of the generic ones of `mixvi extremes` (ssn's residual, agreement
with the conic and homotopy answers, λ ∈ Λ):
- `contact_checks`: the Lemma 4.2 gap |b(u, λ) − Σ g_k W_k |[u]_t,k|| / Σ g_k W_k |[u]_t,k|,
  the friction excess max(|λ_t| − g) relative to max g and the stick/slip counts;
- `homogeneity`: loads and g scaled by s scale (u, λ) by s;
- `expect` counts (all slip / all stick where the data force it); for unilateral contact
  (block3d_liftoff, coulomb_strip3d: F from 0 to 1e3, gaps from 0 to far apart) the open,
  stick and slip zones (`zone_count`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

import vi_core

from ..contract import ExtremeRow

HOMOGENEOUS = 1e-6  # relative deviation from degree-1 homogeneity that fails a row
FRICTION_EXCESS = 1e-9  # relative excess of |λ_t| over g that fails a row
BLOCK, EXT = "block3d", "rigid_foundation_extruded"
LIFT, STRIP = "block3d_liftoff", "coulomb_strip3d"  # unilateral contact, Coulomb friction
G_BLOCK = "1.8e7*(1 + 0.3*x)"  # block3d's friction bound


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def contact_checks(plugin: Any, row: ExtremeRow, model: Any, sol: vi_core.Solution):
    """Lemma 4.2 gap, friction-bound excess and the stick/slip counts of a 3D solution."""
    st = plugin.contact_state(model, sol)
    g, has = st["g"], st["has_t"]
    gmax = float(g.max(initial=0.0))
    mag = np.linalg.norm(st["lam_t_vec"], axis=1)
    excess = float(np.max(mag[has] - g[has], initial=-np.inf))
    stick = int((st["state"] == "stick").sum())  # open nodes (unilateral) are neither
    rec = {
        "lemma_4_2": st["lemma_4_2"] if gmax > 0 else None,
        # the pressure scale: with unilateral contact also the elastic stress (when every node
        # is apart λ is rounding of that size)
        "friction_excess": excess
        / max(gmax, float(np.abs(sol.lam).max(initial=0)), st["pressure"], 1e-300),
        "stick": stick,
        "slip": int(st["slip"].sum()),
    }
    notes = [f"stick {rec['stick']}, slip {rec['slip']}"]
    if rec["friction_excess"] > FRICTION_EXCESS:
        notes.append(f"FAIL: |λ_t| exceeds g by {rec['friction_excess']:.1e} (relative)")
    if rec["lemma_4_2"] is not None and rec["lemma_4_2"] > 1e-10:  # as in 2D: a note (tiny
        # g makes Σ g W |u_t| tiny and the gap rounding over it; the tests hold it to 1e-9)
        notes.append(f"Lemma 4.2 gap {rec['lemma_4_2']:.1e}")
    return rec, notes


def homogeneity(factor: float) -> Callable:
    """Check: loads and g scaled by `factor` must scale (u, λ) by `factor`."""

    def check(plugin: Any, row: ExtremeRow, model: Any, sol: vi_core.Solution):
        base = ExtremeRow(row.name, row.scene, (), row.level).load()
        m0 = plugin.build(base, row.level)
        s0 = vi_core.solve(m0.vi, "ssn")
        h = max(_rel(model.full(sol.u) / factor, m0.full(s0.u)), _rel(sol.lam / factor, s0.lam))
        verdict = "FAIL: not homogeneous" if h > HOMOGENEOUS else "homogeneous of degree 1"
        return {"homogeneity": h}, [f"{verdict} (u/s, λ/s vs the unscaled scene: {h:.1e})"]

    return check


def slip_count(want: str) -> Callable:
    """Check: every tangential node slips ("all") or none does ("none")."""

    def check(plugin: Any, row: ExtremeRow, model: Any, sol: vi_core.Solution):
        st = plugin.contact_state(model, sol)
        n, s = int(st["has_t"].sum()), int(st["slip"].sum())
        ok = s == n if want == "all" else s == 0
        return {}, [] if ok else [f"FAIL: {s} of {n} nodes slip, expected {want}"]

    return check


def zone_count(zone: str, want: str) -> Callable:
    """Check: the nodes in state `zone` ("open", "stick", "slip") are all the nodes carrying
    a normal multiplier (want "all"), none ("none") or some ("some")."""

    def check(plugin: Any, row: ExtremeRow, model: Any, sol: vi_core.Solution):
        st = plugin.contact_state(model, sol)
        n, s = int(model.contact.rows_n.size), int((st["state"] == zone).sum())
        ok = {"all": s == n, "none": s == 0, "some": 0 < s < n}[want]
        return {zone: s}, [] if ok else [f"FAIL: {s} of {n} nodes {zone}, expected {want}"]

    return check


def _scaled(f: float) -> Callable[[dict], None]:
    """The edit scaling block3d's top displacement and g by f."""

    def edit(data: dict) -> None:
        part = data["bodies"]["block"]["displacement"][0]
        part["value"] = [f"({f!r})*({v})" for v in part["value"]]
        data["contact"]["g"] = f"({f!r})*({G_BLOCK})"

    return edit


def _isotropic(data: dict) -> None:
    b = data["bodies"]["block"]
    b["material"] = {"kind": "isotropic", "E": 1e10, "nu": 0.49}
    b.pop("potential", None)


def rows() -> list[ExtremeRow]:
    """The 3D extreme cases (levels 0 and 1: small enough for conic and homotopy)."""
    C = (contact_checks,)
    return [
        ExtremeRow("3D: g = 0 (frictionless)", BLOCK, ["contact.g=0.0"], level=0, checks=C),
        ExtremeRow(
            "3D: g = 1e-6 σ_ref (all slip)",
            BLOCK,
            ["contact.g=18.0"],
            level=0,
            checks=(*C, slip_count("all")),
        ),
        ExtremeRow(
            "3D: g = 1e6 σ_ref (tied)",
            BLOCK,
            ["contact.g=1.8e13"],
            level=0,
            checks=(*C, slip_count("none")),
        ),
        ExtremeRow(
            "3D: g varies 1e8 over Γ3",
            BLOCK,
            ["contact.g='1.8e7*exp(log(1e8)*(x + y)/2 - log(1e4))'"],
            level=0,
            checks=C,
        ),
        ExtremeRow(
            "3D: loads, g × 1e-9",
            BLOCK,
            level=0,
            edit=_scaled(1e-9),
            checks=(*C, homogeneity(1e-9)),
        ),
        ExtremeRow(
            "3D: loads, g × 1e3", BLOCK, level=0, edit=_scaled(1e3), checks=(*C, homogeneity(1e3))
        ),
        ExtremeRow("3D: block, level 1", BLOCK, level=1, checks=C),
        ExtremeRow(
            "3D: PZT-5H poled along (1, 1, 1)",
            BLOCK,
            ["bodies.block.material={name='PZT-5H', poling=[1.0, 1.0, 1.0]}"],
            level=0,
            checks=C,
        ),
        ExtremeRow(
            "3D: curved contact surface",
            BLOCK,
            ["bodies.block.geometry.bottom_lift='0.06*sin(3*x)*cos(2*y)'"],
            level=1,
            checks=C,
        ),
        ExtremeRow(
            "3D: tetrahedra", BLOCK, ["bodies.block.geometry.element='tetra'"], level=1, checks=C
        ),
        ExtremeRow("3D: ν = 0.49 (elastic)", BLOCK, level=0, edit=_isotropic, checks=C),
        ExtremeRow("3D: extruded 2D scene (discs + lines)", EXT, level=0, checks=C),
        ExtremeRow(
            "3D unilateral: Coulomb F = 0 (frictionless)",
            LIFT,
            ["contact.F=0.0"],
            level=0,
            checks=(*C, zone_count("stick", "none"), zone_count("open", "some")),
        ),
        ExtremeRow(
            "3D unilateral: Coulomb F = 0.6",
            LIFT,
            level=1,
            checks=(*C, zone_count("stick", "some"), zone_count("slip", "some")),
        ),
        ExtremeRow(
            "3D unilateral: Coulomb F = 1e3 (stick where touching)",
            LIFT,
            ["contact.F=1e3"],
            level=0,
            checks=(*C, zone_count("slip", "none")),
        ),
        ExtremeRow(
            "3D unilateral: F varies 1e4 over Γ3",
            LIFT,
            ["contact.F='0.01*exp(log(1e4)*(x + y)/2)'"],
            level=0,
            checks=C,
        ),
        ExtremeRow(
            "3D unilateral: gap 2e-7..4e-7 (partly closed)",
            LIFT,
            ["contact.gap='2e-7*(1 + y)'"],
            level=0,
            checks=(*C, zone_count("open", "some")),
        ),
        ExtremeRow(
            "3D unilateral: gap 1e-3 (apart, λ = 0)",
            STRIP,
            ["contact.gap=1e-3"],
            level=0,
            checks=(*C, zone_count("open", "all")),
        ),
        ExtremeRow(
            "3D unilateral: Coulomb strip (closed form)",
            STRIP,
            level=0,
            checks=(*C, zone_count("slip", "all")),
        ),
        ExtremeRow(
            "3D: extruded, aspect ratio 1e3",
            EXT,
            ["bodies.block.geometry.z=[0.0, 1e-3]"],
            level=0,
            checks=C,
        ),
    ]
