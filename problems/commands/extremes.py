"""`mixvi extremes`: the shipped scenes pushed to extreme data, each row checked and reported.

Every row builds a variant of a shipped scene (`load_scene(name, overrides)`, plus a direct
edit where an override cannot delete a key), solves it with semismooth Newton and, where
affordable, with the conic (Clarabel) and homotopy methods, and reports
- the relative natural-map residual and Newton steps of ssn,
- the largest relative difference of (u, λ) between ssn and the other methods' raw answers
  (conic without polishing),
- a physical check: the Lemma 4.2 gap |b(u, λ) − ∫g|[u_τ]|| / ∫g|[u_τ]|, the friction bound
  (max(|λ_τ| − g) / max g ≤ 0 up to rounding), stick/slip counts, and row-specific ones
  (homogeneity of degree 1 under scaled data, the homotopy's ρ and levels, locking),
- a note that says what failed or what limitation shows, in plain words.

σ_ref of a scene is the friction bound it ships with (9e6 Pa rigid_foundation, 1e8 Pa
paper_two_body), which is of the order of its contact stresses.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import vi_core
from problems.errors import SceneError
from problems.output.files import output_folder
from problems.plugins import piezo_contact as pc
from problems.scene import Scene, load_scene

from . import resources

RESIDUAL_OK = 1e-8
AGREE_OK = 1e-6
CONIC_MAX = 20_000  # unknowns: above this the conic method is skipped (time)
HOMOTOPY_MAX = 3_000  # unknowns: above this the homotopy method is skipped (time)
SIGMA_REF = {"rigid_foundation": 9.0e6, "paper_two_body": 1.0e8}


@dataclass
class Row:
    """One extreme case: a scene variant, its level, and an optional extra physical check."""

    name: str
    scene: str
    overrides: list[str] = field(default_factory=list)
    level: int = 1
    edit: Callable[[dict], None] | None = None
    extra: Callable[[Row, pc.Model, vi_core.Solution], dict] | None = None
    huge: bool = False

    def load(self, extra_overrides: tuple[str, ...] = ()) -> Scene:
        scene = load_scene(self.scene, [*self.overrides, *extra_overrides])
        if self.edit is not None:
            self.edit(scene.data)
        return scene


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def contact_checks(model: pc.Model, sol: vi_core.Solution) -> dict:
    """Lemma 4.2 gap, friction-bound violation and stick/slip counts of a solution."""
    st = pc.contact_state(model, sol)
    g = st["g"]
    gmax = float(g.max(initial=0.0))
    excess = float(np.max(np.abs(st["lam_t"]) - g))
    return {
        "lemma_4_2": st["lemma_4_2"] if gmax > 0 else None,
        "friction_excess": excess / max(gmax, float(np.abs(sol.lam).max(initial=0)), 1e-300),
        "stick": int((~st["slip"]).sum()),
        "slip": int(st["slip"].sum()),
    }


def homogeneity(factor: float, overrides: tuple[str, ...]) -> Callable:
    """Extra check: data scaled by `factor` (loads and g) must scale (u, λ) by `factor`."""

    def check(row: Row, model: pc.Model, sol: vi_core.Solution) -> dict:
        base = Row(row.name, row.scene, [], row.level, row.edit).load(overrides)
        m0 = pc.build(base, row.level)
        s0 = vi_core.solve(m0.vi, "ssn")
        du = _rel(model.full(sol.u) / factor, m0.full(s0.u))
        dl = _rel(sol.lam / factor, s0.lam)
        return {"homogeneity": max(du, dl)}

    return check


def locking(row: Row, model: pc.Model, sol: vi_core.Solution) -> dict:
    """Extra check: resultant normal contact force ∑ λ_n,k W_k on this and two finer levels
    (W_k = ∫φ̃_k, the weight of normal multiplier row k)."""
    forces = []
    for lev in (row.level, row.level + 1, row.level + 2):
        m = model if lev == row.level else pc.build(row.load(), lev)
        s = sol if lev == row.level else vi_core.solve(m.vi, "ssn")
        n_n, _ = m.contact.sizes
        forces.append(float(np.sum(s.lam[:n_n] * m.contact.W_n)))
    return {
        "normal_force_levels": forces,
        "locking_overestimate": forces[0] / forces[-1] - 1.0,
    }


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


def rows() -> list[Row]:
    """The extreme cases, cheapest first within each group."""
    return [
        Row("g = 0 (frictionless)", RF, ["contact.g=0.0"]),
        Row("g = 1e-6 σ_ref", RF, [f"contact.g={1e-6 * S_RF!r}"]),
        Row("g = 1e6 σ_ref", RF, [f"contact.g={1e6 * S_RF!r}"]),
        Row(
            "g varies 1e8 along Γ3",
            RF,
            [f"contact.g='{S_RF!r}*exp(log(1e8)*x/2 - log(1e4))'"],
        ),
        Row("loads, g × 1e-12", RF, list(_scaled(1e-12)), extra=homogeneity(1e-12, ())),
        Row("loads, g × 1e3", RF, list(_scaled(1e3)), extra=homogeneity(1e3, ())),
        Row("BaTiO3", RF, level=0),
        Row("PZT-5H", RF, ["bodies.block.material='PZT-5H'"], level=0),
        Row("BaTiO3 coupling × 4 (ρ > 2)", RF, [_coupled(4.0)], level=0),
        Row(
            "ν = 0.49",
            RF,
            level=1,
            edit=_drop_potential("block", {"kind": "isotropic", "E": 1e10, "nu": 0.49}),
            extra=locking,
        ),
        Row(
            "ν = 0.4999",
            RF,
            level=1,
            edit=_drop_potential("block", {"kind": "isotropic", "E": 1e10, "nu": 0.4999}),
            extra=locking,
        ),
        Row("aspect ratio 1e3 (thin layer)", RF, ["bodies.block.geometry.y=[0.0, 1e-3]"]),
        Row(
            "slave 10× coarser than master",
            PT,
            ["bodies.disc.geometry.n_contact=4", "bodies.cradle.geometry.n_contact=40"],
            level=0,
        ),
        Row(
            "slave 10× finer than master",
            PT,
            ["bodies.disc.geometry.n_contact=40", "bodies.cradle.geometry.n_contact=4"],
            level=0,
        ),
        Row("paper scene, level 6 (~1.6M unknowns)", PT, level=6, huge=True),
    ]


def run_row(row: Row) -> dict:
    """Solve one row with every affordable method and collect the checks."""
    t0 = time.perf_counter()
    model = pc.build(row.load(), row.level)
    vi = model.vi
    n = vi.n + vi.m
    sol = vi_core.solve(vi, "ssn")
    rec: dict = {
        "row": row.name,
        "scene": row.scene,
        "level": row.level,
        "unknowns": n,
        "converged": sol.converged,
        "residual": sol.residual,
        "iterations": {"ssn": sol.iterations},
        "agreement": {},
        "notes": [],
    }
    others = []
    if vi.structure != "general" and n <= CONIC_MAX:
        others.append("conic")
    if n <= HOMOTOPY_MAX:
        others.append("homotopy")
    for meth in others:
        # raw answers: the conic one as Clarabel returns it (polishing would make it ssn's)
        opts = {"max_levels": 12} if meth == "homotopy" else {"polish": 0}
        other = vi_core.solve(vi, meth, **opts)
        rec["iterations"][meth] = other.iterations
        if meth == "homotopy":
            rec["rho"] = other.info.get("rho")
            rec["homotopy_levels"] = max(len(other.info.get("levels", [])) - 1, 0)
        failed = other.info.get("status") != "optimal" if meth == "conic" else not other.converged
        if failed:
            rec["notes"].append(f"{meth} did not converge (residual {other.residual:.1e})")
        du = _rel(model.full(other.u), model.full(sol.u))  # with Dirichlet values: data scale
        diff = max(du, _rel(other.lam, sol.lam) if vi.m else 0.0)
        rec["agreement"][meth] = diff
    rec.update(contact_checks(model, sol))
    if row.extra is not None:
        rec.update(row.extra(row, model, sol))
    rec["warnings"] = model.warnings + sol.warnings
    rec["time_s"] = time.perf_counter() - t0
    rec["notes"] += _verdict(rec)
    rec["ok"] = not any(x.startswith("FAIL") for x in rec["notes"])
    return rec


def _verdict(rec: dict) -> list[str]:
    """Plain-words judgement of a record against the thresholds."""
    notes = []
    if not rec["converged"] or rec["residual"] > RESIDUAL_OK:
        notes.append(f"FAIL: ssn residual {rec['residual']:.1e}")
    worst = max(rec["agreement"].values(), default=0.0)
    if worst > AGREE_OK:
        bad = ", ".join(f"{k} {v:.1e}" for k, v in rec["agreement"].items() if v > AGREE_OK)
        notes.append(f"FAIL: methods disagree ({bad})")
    if not rec["agreement"]:
        notes.append("ssn only (too large for conic/homotopy)")
    if rec["friction_excess"] > 1e-9:
        notes.append(f"FAIL: |λ_τ| exceeds g by {rec['friction_excess']:.1e} (relative)")
    if rec.get("lemma_4_2") is not None and rec["lemma_4_2"] > 1e-10:
        notes.append(f"Lemma 4.2 gap {rec['lemma_4_2']:.1e}")
    if "homogeneity" in rec:
        h = rec["homogeneity"]
        verdict = "FAIL: not homogeneous" if h > 1e-6 else "homogeneous of degree 1"
        notes.append(f"{verdict} (u/s, λ/s vs the unscaled scene: {h:.1e})")
    if "locking_overestimate" in rec:
        notes.append(
            f"locking: normal force {100 * rec['locking_overestimate']:.1f}% above the level "
            f"{rec['level'] + 2} value (lowest-order elements)"
        )
    if "rho" in rec:
        notes.append(f"ρ = {rec['rho']:.2f}, {rec['homotopy_levels']} homotopy levels")
    return notes


def format_row(rec: dict) -> str:
    its = "/".join(str(v) for v in rec["iterations"].values())
    agree = max(rec["agreement"].values(), default=float("nan"))
    lemma = rec["lemma_4_2"]
    return (
        f"{rec['row']:<34}{rec['unknowns']:>8}{rec['residual']:>10.1e}{agree:>10.1e}"
        f"{its:>10}{'—' if lemma is None else f'{lemma:.1e}':>9}"
        f"{rec['stick']:>6}{rec['slip']:>5}  {'; '.join(rec['notes'])}"
    )


HEADER = (
    f"{'row':<34}{'unknowns':>8}{'residual':>10}{'agree':>10}{'iters':>10}{'lemma':>9}"
    f"{'stick':>6}{'slip':>5}  note"
)


def extremes_main(argv: list[str]) -> int:
    """`mixvi extremes [--huge] [--only TEXT] [--out DIR]`: 0 if every row passes, else 1."""
    p = argparse.ArgumentParser(prog="mixvi extremes", description=__doc__.splitlines()[0])
    p.add_argument("--huge", action="store_true", help="include the ~1.6M-unknown row")
    p.add_argument("--only", default=None, help="run only rows whose name contains TEXT")
    p.add_argument("--out", default="out/extremes", help="directory for extremes.json")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="write into a folder that holds other files (nothing is deleted)",
    )
    p.add_argument(
        "--force", action="store_true", help="run rows whose memory estimate does not fit"
    )
    args = p.parse_args(argv)
    candidates = [r for r in rows() if args.huge or not r.huge]
    selected = [r for r in candidates if args.only is None or args.only in r.name]
    if not selected:
        raise SceneError(
            "--only",
            args.only,
            "text contained in a row name: " + "; ".join(r.name for r in candidates),
        )
    for row in selected:  # every row's level must fit in memory before anything runs
        option = "--huge" if row.huge else "--only"
        resources.check_levels(pc, row.load(), (row.level, row.level), option, row.name, args.force)
    with output_folder(args.out, "--out", overwrite=args.overwrite) as folder:
        print("iters = ssn/conic/homotopy; agree = largest relative difference to ssn")
        print(HEADER)
        records = []
        for row in selected:
            rec = run_row(row)
            records.append(rec)
            print(format_row(rec), flush=True)
        with folder.staging() as tmp:
            text = json.dumps(records, indent=2, default=float) + "\n"
            (tmp / "extremes.json").write_text(text)
    print(f"wrote {Path(args.out) / 'extremes.json'}")
    return 0 if all(r["ok"] for r in records) else 1
