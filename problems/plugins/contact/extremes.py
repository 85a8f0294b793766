"""The `mixvi extremes` rows of the contact plug-in (contract v2 `extremes()`), 2D and 3D: the
shipped contact scenes pushed to extreme friction bounds, data scales, materials, poling
directions, curved contact surfaces, near-incompressibility, mesh ratios, and for unilateral
contact (coulomb_slip, piezo_liftoff, block3d_liftoff, coulomb_strip3d: F from 0 to 1e3, gaps
from 0 to far apart) the open, stick and slip zones.

Each row's checks, on top of the generic ones of `mixvi extremes` (ssn's residual, agreement
with the conic and homotopy answers, λ ∈ Λ):
- `contact_checks`: the Lemma 4.2 gap |b(u, λ) − Σ ρ_k W_k |[u]_t,k|| / Σ ρ_k W_k |[u]_t,k|, the
  friction bound (max(|λ_t| − ρ) relative to the stress scale ≤ 0 up to rounding) and the
  stick/slip counts, for a 2D node (one tangent) and a 3D one (a disc or a line) alike;
- `homogeneity`: data scaled by s (loads and g) scale (u, λ) by s;
- `locking`: the resultant normal contact force on this and two finer levels (2D);
- `expect` counts, `slip_count`, `zone_count`: the zones where the data force them.

σ_ref of a 2D scene is the friction bound it ships with (9e6 Pa rigid_foundation, 1e8 Pa
paper_two_body), which is of the order of its contact stresses.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np

import vi_core
from problems.scene.contact_references import (
    Layer,
    two_layer_electrical_contact,
    uniaxial_electrical_contact,
)

from ..contract import Checks, ExtremeRow, expect, relative_difference, solve_model

SIGMA_REF = {"rigid_foundation": 9.0e6, "paper_two_body": 1.0e8}
HOMOGENEOUS = 1e-6  # relative deviation from degree-1 homogeneity that fails a row
FRICTION_EXCESS = 1e-9  # relative excess of |λ_t| over g that fails a row


def contact_checks(plugin: Any, row: ExtremeRow, model: Any, sol: vi_core.Solution):
    """Lemma 4.2 gap, friction-bound violation and stick/slip counts of a solution (2D: per
    tangential row; 3D: per surface node with a tangential row, |λ_t| the disc's radius)."""
    if model.contact is None:
        return {}, ["no contact interface"]
    st = plugin.contact_state(model, sol)
    g = st["g"]
    gmax = float(g.max(initial=0.0))
    if "lam_t_vec" in st:  # 3D
        mag, g_t = np.linalg.norm(st["lam_t_vec"], axis=1)[st["has_t"]], g[st["has_t"]]
    else:
        mag, g_t = np.abs(st["lam_t"]), g
    excess = float(np.max(mag - g_t, initial=-np.inf))
    # the pressure scale: with unilateral contact also the elastic stress (when every node is
    # apart λ is rounding of that size)
    scale = max(gmax, float(np.abs(sol.lam).max(initial=0)), st.get("pressure", 0.0), 1e-300)
    rec = {
        "lemma_4_2": st["lemma_4_2"] if gmax > 0 else None,
        "friction_excess": excess / scale,
        "stick": int(np.sum(st["state"] == "stick")),  # open nodes (unilateral) are neither
        "slip": int(st["slip"].sum()),
    }
    notes = [f"stick {rec['stick']}, slip {rec['slip']}"]
    if rec["friction_excess"] > FRICTION_EXCESS:
        notes.append(f"FAIL: |λ_t| exceeds g by {rec['friction_excess']:.1e} (relative)")
    if rec["lemma_4_2"] is not None and rec["lemma_4_2"] > 1e-10:  # a note (tiny g makes
        # Σ g W |u_t| tiny and the gap rounding over it; the tests hold it to 1e-9)
        notes.append(f"Lemma 4.2 gap {rec['lemma_4_2']:.1e}")
    return rec, notes


def homogeneity(factor: float, scaled_by_edit: bool = False) -> Callable:
    """Check: data scaled by `factor` (loads and g) must scale (u, λ) by `factor`; the
    unscaled scene is the row's without its overrides (and without its edit if
    `scaled_by_edit`: the edit is the scaling)."""

    def check(plugin: Any, row: ExtremeRow, model: Any, sol: vi_core.Solution):
        edit = None if scaled_by_edit else row.edit
        base = ExtremeRow(row.name, row.scene, (), row.level, edit).load()
        m0 = plugin.build(base, row.level)
        s0 = solve_model(plugin, m0, method="ssn")
        du = relative_difference(model.full(sol.u) / factor, m0.full(s0.u))
        h = max(du, relative_difference(sol.lam / factor, s0.lam))
        verdict = "FAIL: not homogeneous" if h > HOMOGENEOUS else "homogeneous of degree 1"
        return {"homogeneity": h}, [f"{verdict} (u/s, λ/s vs the unscaled scene: {h:.1e})"]

    return check


def locking(plugin: Any, row: ExtremeRow, model: Any, sol: vi_core.Solution):
    """Resultant normal contact force ∑ λ_n,k W_k on this and two finer levels (W_k = ∫φ̃_k,
    the weight of normal multiplier row k): lowest-order elements lock, the force drops."""
    forces = []
    for lev in (row.level, row.level + 1, row.level + 2):
        m = model if lev == row.level else plugin.build(row.load(), lev)
        s = sol if lev == row.level else plugin.solve(m, method="ssn")
        forces.append(float(np.sum(m.contact.normal(s.lam) * m.contact.W_n[m.contact.rows_n])))
    over = forces[0] / forces[-1] - 1.0
    note = (
        f"locking: normal force {100 * over:.1f}% above the level {row.level + 2} value "
        "(lowest-order elements)"
    )
    return {"normal_force_levels": forces, "locking_overestimate": over}, [note]


def uniaxial_electrical_defect(model: Any, sol: vi_core.Solution) -> dict[str, float]:
    """A block in uniaxial strain on a conductive (or grounded) foundation (electrical_block),
    or on a second such block (electrical_two_body, its bottom fixed): the interface
    potentials and pressure of `sol` against the closed form
    (`contact_references.uniaxial_electrical_contact`, `two_layer_electrical_contact`), with
    the thicknesses from the meshes and the load δ and outer potentials read from the model's
    prescribed values. Returns {"phi": max|φ − φ_ref| / max(|φ_ref|, |φ_F|, |V|, 1) over the
    slave's φ (and the master's Πφ), "lam": max|λ_n − λ_ref| / |λ_ref|}."""
    c, slave, master = model.electrical, model.contact.slave, model.contact.master
    x = model.full(sol.u)  # (n_full,) with the Dirichlet values

    def layer(body: Any, side: str) -> tuple[Layer, np.ndarray]:
        M = body.material
        H = float(np.ptp(body.mesh.points[:, 1]))
        nodes = np.unique(body.mesh.boundaries[side])  # (k,) nodes of the outer edge
        return Layer(M.C[1, 1], M.e[1, 1], M.kappa[1, 1], H), nodes

    top_layer, top = layer(slave, "top")
    delta = -float(np.mean(x[slave.u_dofs(top)[:, 1]]))
    V = float(np.mean(x[slave.phi_dofs(top)]))

    def k(lam: float) -> float:
        return float(c.law(np.array([lam]))[0])

    phi_s = sol.u[c.phi]  # (N,)
    if c.master is None:
        one = uniaxial_electrical_contact(
            top_layer.c33, top_layer.e33, top_layer.k33, top_layer.H, delta, V, c.phi_F, k
        )
        refs, lam_ref, outer = [(phi_s, one.phi0)], one.lam_n, c.phi_F
    else:
        base, bottom = layer(master, "bottom")
        V_m = float(np.mean(x[master.phi_dofs(bottom)]))
        two = two_layer_electrical_contact(top_layer, base, delta, V, V_m, k)
        phi_m = c.master @ sol.u + c.fixed  # (N,) Πφ_m
        refs, lam_ref, outer = [(phi_s, two.phi_s), (phi_m, two.phi_m)], two.lam_n, V_m
    scale = max(*(abs(r) for _, r in refs), abs(outer), abs(V), 1.0)
    return {
        "phi": max(float(np.abs(v - r).max()) for v, r in refs) / scale,
        "lam": float(np.abs(sol.lam[c.normal] - lam_ref).max()) / max(abs(lam_ref), 1e-300),
    }


# Q1 holds the uniaxial fields exactly, so the defect is the rounding of the solve: κ·ε of the
# piezoelectric system, not the Newton tolerance (grounded two-body row, V = 100 V: φ 2.2e-8
# with SuperLU at tol 1e-10, 1e-12 and 1e-14 alike, 1.4e-8 with PARDISO, 3.9e-7 with AMG at its
# Krylov tolerance; below 1e-8 with SuperLU on the machine of earlier CI runs, so 1e-8 was at
# the floor). A wrong law, sign or coupling is off by O(1) (tests/problems/plugins/
# test_electrical_contact.py's fault injections).
ELECTRICAL_MATCH = 1e-7


def electrical_checks(plugin: Any, row: ExtremeRow, model: Any, sol: vi_core.Solution):
    """Check: the uniaxial closed form (`uniaxial_electrical_defect`) within ELECTRICAL_MATCH,
    and the outer fixed point's steps."""
    d = uniaxial_electrical_defect(model, sol)
    outer = sol.info.get("electrical", {})
    rec = {"electrical_phi": d["phi"], "electrical_lam": d["lam"]}
    rec["electrical_steps"] = outer.get("iterations")
    notes = [
        f"closed form: φ {d['phi']:.1e}, λ_n {d['lam']:.1e}; {rec['electrical_steps']} k-steps"
    ]
    if not max(d.values()) <= ELECTRICAL_MATCH:
        notes.append(f"FAIL: off the uniaxial closed form by {max(d.values()):.1e}")
    return rec, notes


def _drop_potential(body: str, material: dict) -> Callable[[dict], None]:
    def edit(data: dict) -> None:
        b = data["bodies"][body]
        b["material"] = material
        b.pop("potential", None)
        data.get("output", {}).pop("potential_along", None)

    return edit


def _coupled(scale: float) -> str:
    return f"bodies.block.material={{name='BaTiO3', coupling_scale={scale}}}"


RF, PT = "rigid_foundation", "paper_two_body"
S_RF = SIGMA_REF[RF]
LOAD_RF = "bodies.block.displacement=[{{boundary='top', value=[{a!r}, {b!r}]}}]"


def _scaled(f: float) -> tuple[str, ...]:
    return (LOAD_RF.format(a=2e-4 * f, b=-1e-4 * f), f"contact.g={S_RF * f!r}")


def counts(model: Any, sol: vi_core.Solution) -> dict[str, int]:
    """Touching, open, stick and slip nodes along Γ3 (`contact_state.contact_state`)."""
    st = model.contact_state(sol)
    return {
        "touching": int(st["touch"].sum()),
        "open": int(np.sum(st["normal_state"] == "open")),
        "stick": int(np.sum(st["state"] == "stick")),
        "slip": int(st["slip"].sum()),
    }


def _voltage(v: float) -> str:
    return (
        f"bodies.block.potential=[{{boundary='top', value={v!r}}}, "
        "{boundary='bottom', value=0.0}]"
    )


CS, LO = "coulomb_slip", "piezo_liftoff"


def _row(name: str, scene: str, overrides: Sequence[str] = (), *checks: Checks, **kw: Any):
    """An ExtremeRow checked by `contact_checks` and `checks` (kw: its level, edit, huge)."""
    return ExtremeRow(name, scene, overrides, checks=(contact_checks, *checks), **kw)


def unilateral_rows() -> list[ExtremeRow]:
    """Unilateral contact with Coulomb friction: F over the range where Newton and the fixed
    point agree (docs/coulomb.md, "Scenes"), gaps that close, voltages that close and open
    the contact. A gap the block never closes is not a row: every λ is then rounding, and the
    fixed point's conic λ (1e-5 of the answer's size, measured at gap 0.2–10 μm, while u agrees
    to 1e-13) fails the generic agreement check;
    tests/problems/plugins/contact/test_plane_unilateral.py checks that case directly."""
    return [
        _row("Coulomb F = 0", CS, ["contact.F=0.0"], expect(counts, stick=0)),
        _row("Coulomb F = 0.3 (partial stick)", CS, ["contact.F=0.3"]),
        _row("Coulomb F = 10 (stick)", CS, ["contact.F=10.0"], expect(counts, slip=0)),
        _row("Coulomb F = 1e6 (stick)", CS, ["contact.F=1e6"], expect(counts, slip=0)),
        _row("gap = 0", LO, ["contact.gap=0.0"], expect(counts, open=0)),
        _row("gap = 1e-8 m (closes)", LO, ["contact.gap=1e-8"], expect(counts, open=0)),
        _row("V = −500 V (pressed)", LO, [_voltage(-500.0)], expect(counts, open=0)),
        _row("V = 700 V (ends lift off)", LO, [_voltage(700.0)], expect(counts, open="> 0")),
        _row("V = 1000 V (lifted off)", LO, [_voltage(1000.0)], expect(counts, touching=0)),
    ]


EB, ET = "electrical_block", "electrical_two_body"


def _pull_top(data: dict) -> None:
    """electrical_block's top pulled up by 1 μm instead of pressed: the contact in tension."""
    top = next(d for d in data["bodies"]["block"]["displacement"] if d["boundary"] == "top")
    top["value"] = [0.0, 1e-6]


def electrical_rows() -> list[ExtremeRow]:
    """[contact.electrical] on the uniaxial block: conductances from tiny to the grounded
    limit, and pulled apart (tension: k = 0); the same block on a second one through the dual
    mortar (non-matching meshes); each against its closed form."""
    E = electrical_checks
    return [
        _row("electrical: conductive k0 = 2e-12 (≈ insulating)", EB,
             ["contact.electrical.k0=2e-12"], E),
        _row("electrical: conductive k0 = 2e-2 (≈ grounded)", EB,
             ["contact.electrical.k0=2e-2"], E),
        _row("electrical: grounded", EB, ['contact.electrical.kind="grounded"'], E),
        _row("electrical: pulled apart (k = 0)", EB, (), E, edit=_pull_top),
        _row("electrical, two bodies: conductive", ET, (), E),
        _row("electrical, two bodies: k0 = 2e-2", ET, ["contact.electrical.k0=2e-2"], E),
        # V = 100 V on top: with 0 V on both outer faces the grounded interface potential is 0
        # by symmetry, and the relative agreement of a zero field would measure rounding.
        # Level 0: the penalty makes est‖J⁻¹‖₁ ≈ 3e8, and at level 1 Clarabel's raw answer
        # differs by 3.4e-5 (above AGREE_OK; `mixvi check` allows it, κ-scaled)
        _row("electrical, two bodies: grounded, V = 100 V", ET,
             ['contact.electrical.kind="grounded"',
              "bodies.block.potential=[{boundary='top', value=100.0}]"], E, level=0),
    ]  # fmt: skip


def rows_2d() -> list[ExtremeRow]:
    """The extreme cases, cheapest first within each group."""
    return [
        *unilateral_rows(),
        *electrical_rows(),
        _row("g = 0 (frictionless)", RF, ["contact.g=0.0"]),
        _row("g = 1e-6 σ_ref", RF, [f"contact.g={1e-6 * S_RF!r}"]),
        _row("g = 1e6 σ_ref", RF, [f"contact.g={1e6 * S_RF!r}"]),
        _row("g varies 1e8 along Γ3", RF, [f"contact.g='{S_RF!r}*exp(log(1e8)*x/2 - log(1e4))'"]),
        _row("loads, g × 1e-12", RF, list(_scaled(1e-12)), homogeneity(1e-12)),
        _row("loads, g × 1e3", RF, list(_scaled(1e3)), homogeneity(1e3)),
        _row("BaTiO3", RF, level=0),
        _row("PZT-5H", RF, ["bodies.block.material='PZT-5H'"], level=0),
        _row("BaTiO3 coupling × 4 (ρ > 2)", RF, [_coupled(4.0)], level=0),
        _row(
            "ν = 0.49",
            RF,
            (),
            locking,
            level=1,
            edit=_drop_potential("block", {"kind": "isotropic", "E": 1e10, "nu": 0.49}),
        ),
        _row(
            "ν = 0.4999",
            RF,
            (),
            locking,
            level=1,
            edit=_drop_potential("block", {"kind": "isotropic", "E": 1e10, "nu": 0.4999}),
        ),
        _row("aspect ratio 1e3 (thin layer)", RF, ["bodies.block.geometry.y=[0.0, 1e-3]"]),
        _row(
            "slave 10× coarser than master",
            PT,
            ["bodies.disc.geometry.n_contact=4", "bodies.cradle.geometry.n_contact=40"],
            level=0,
        ),
        _row(
            "slave 10× finer than master",
            PT,
            ["bodies.disc.geometry.n_contact=40", "bodies.cradle.geometry.n_contact=4"],
            level=0,
        ),
        _row("paper scene, level 6 (~1.6M unknowns)", PT, level=6, huge=True),
    ]


# ------------------------------------------------------------------ 3D rows
BLOCK, EXT = "block3d", "rigid_foundation_extruded"
LIFT, STRIP = "block3d_liftoff", "coulomb_strip3d"  # unilateral contact, Coulomb friction
G_BLOCK = "1.8e7*(1 + 0.3*x)"  # block3d's friction bound


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


def _scaled_block(f: float) -> Callable[[dict], None]:
    """The edit scaling block3d's top displacement and g by f."""

    def edit(data: dict) -> None:
        part = data["bodies"]["block"]["displacement"][0]
        part["value"] = [f"({f!r})*({v})" for v in part["value"]]
        data["contact"]["g"] = f"({f!r})*({G_BLOCK})"

    return edit


def rows_3d() -> list[ExtremeRow]:
    """The 3D extreme cases (levels 0 and 1: small enough for conic and homotopy)."""
    row = partial(_row, level=0)  # level 1 where a row says so
    return [
        row("3D: g = 0 (frictionless)", BLOCK, ["contact.g=0.0"]),
        row("3D: g = 1e-6 σ_ref (all slip)", BLOCK, ["contact.g=18.0"], slip_count("all")),
        row("3D: g = 1e6 σ_ref (tied)", BLOCK, ["contact.g=1.8e13"], slip_count("none")),
        row(
            "3D: g varies 1e8 over Γ3",
            BLOCK,
            ["contact.g='1.8e7*exp(log(1e8)*(x + y)/2 - log(1e4))'"],
        ),
        row(
            "3D: loads, g × 1e-9",
            BLOCK,
            (),
            homogeneity(1e-9, scaled_by_edit=True),
            edit=_scaled_block(1e-9),
        ),
        row(
            "3D: loads, g × 1e3",
            BLOCK,
            (),
            homogeneity(1e3, scaled_by_edit=True),
            edit=_scaled_block(1e3),
        ),
        row("3D: block, level 1", BLOCK, level=1),
        row(
            "3D: PZT-5H poled along (1, 1, 1)",
            BLOCK,
            ["bodies.block.material={name='PZT-5H', poling=[1.0, 1.0, 1.0]}"],
        ),
        row(
            "3D: curved contact surface",
            BLOCK,
            ["bodies.block.geometry.bottom_lift='0.06*sin(3*x)*cos(2*y)'"],
            level=1,
        ),
        row("3D: tetrahedra", BLOCK, ["bodies.block.geometry.element='tetra'"], level=1),
        row(
            "3D: ν = 0.49 (elastic)",
            BLOCK,
            edit=_drop_potential("block", {"kind": "isotropic", "E": 1e10, "nu": 0.49}),
        ),
        row("3D: extruded 2D scene (discs + lines)", EXT),
        row(
            "3D unilateral: Coulomb F = 0 (frictionless)",
            LIFT,
            ["contact.F=0.0"],
            zone_count("stick", "none"),
            zone_count("open", "some"),
        ),
        row(
            "3D unilateral: Coulomb F = 0.6",
            LIFT,
            (),
            zone_count("stick", "some"),
            zone_count("slip", "some"),
            level=1,
        ),
        row(
            "3D unilateral: Coulomb F = 1e3 (stick where touching)",
            LIFT,
            ["contact.F=1e3"],
            zone_count("slip", "none"),
        ),
        row(
            "3D unilateral: F varies 1e4 over Γ3",
            LIFT,
            ["contact.F='0.01*exp(log(1e4)*(x + y)/2)'"],
        ),
        row(
            "3D unilateral: gap 2e-7..4e-7 (partly closed)",
            LIFT,
            ["contact.gap='2e-7*(1 + y)'"],
            zone_count("open", "some"),
        ),
        row(
            "3D unilateral: gap 1e-3 (apart, λ = 0)",
            STRIP,
            ["contact.gap=1e-3"],
            zone_count("open", "all"),
        ),
        row(
            "3D unilateral: Coulomb strip (closed form)",
            STRIP,
            (),
            zone_count("slip", "all"),
        ),
        row("3D: extruded, aspect ratio 1e3", EXT, ["bodies.block.geometry.z=[0.0, 1e-3]"]),
    ]
