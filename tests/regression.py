"""Regression of the shipped scenes: the same answers as the stored baselines, to rounding.

    python -m tests.regression [--write] [--levels 0,1] [--scenes a,b]

solves every shipped scene (problems/scenes/*.toml) at levels 0 and 1 (LEVEL_0_ONLY: 0 only)
and compares its summary with tests/baselines/SCENE.json; `--write` stores the current
summaries as the new baselines (do that only for a change of the answers that is meant, and
say why in the commit).

What is compared (`summary`): the unknowns per field, the norms of the solution per field
(‖u‖, ‖φ‖ through `Model.unknown_fields()` where the model has it) and of the multiplier ‖λ‖,
the energy uᵀAu, ‖Bu − gap‖, and every entry of the plug-in's `postprocess` summary (contact
counts, errors against exact solutions, force resultants, ...) except the rounding residues
listed in RESIDUES: quantities that are zero in exact arithmetic (a force imbalance, a Lemma 4.2
gap, a complementarity defect, a mortar patch defect) are the rounding of the residual, not an
answer, and differ from run to run at the 1e-16 level.

The tolerance (`tolerance`), derived rather than chosen. Both the baseline and the rerun are
solved by semismooth Newton to relative natural-map residuals r₀, r₁ (measured: ≤ 1e-14 on every
shipped scene, Newton converges quadratically down to rounding), so each lies within κ·rᵢ of
the exact discrete solution in the equilibrated variables, κ = est‖J⁻¹‖₁ of the natural map's
Jacobian (recorded with each baseline; measured ≤ 3.1e3 at levels 0 and 1). Two runs therefore
differ by at most κ·(r₀ + r₁) relatively; every compared quantity is a norm, an inner product
or a linear functional of the solution, so it moves by at most that relative amount of its
size as well (twice for the quadratic uᵀAu). The tolerance is SAFETY · κ · (r₀ + r₁ + 4ε),
SAFETY = 1e3 covering the norm equivalences between equilibrated and physical variables and a
different BLAS/LU ordering; with the measured κ and r it lies between 1e-10 and 1e-8 — far below
any change of the discretisation (a perturbation of the data by 1e-6 is caught, see
tests/test_regression.py). Integers and strings (dofs, contact counts, node lists, the master's
name) must match exactly. A vector (a force resultant) is compared by its norm: its components
near zero are rounding of the opposing forces, measured relative to the resultant.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from problems.pipeline import solve_model
from problems.plugins import registry
from problems.scene import SCENES_DIR, load_scene

BASELINES = Path(__file__).resolve().parent / "baselines"
LEVELS = (0, 1)
# The two gmsh scenes are compared at level 0 only: at level 1 their derived tolerance
# (SAFETY·κ·residual, 3.1e-8 for plate_with_hole and 2.5e-8 for wavy_two_body at baseline time)
# is above the 1e-8 bound at which test_regression still calls it a rounding tolerance, and the
# bound is not loosened for them. Level 0 covers their mesh import, build and solve path.
# The two Hertz scenes likewise: their graded meshes (cells down to h^1.5-size at the first
# contact point) give κ ≈ 1e4 at level 1 and a derived tolerance of 1.2e-8 / 8.3e-9 there.
# The 3D scenes too (the CI budget of the 3D tests; their level 1 is compared with the 2D
# plug-in and the other methods in tests/problems/plugins/contact/test_solid.py and test_check3d.py;
# the two-body ones in test_contact3d_two_body.py).
LEVEL_0_ONLY = (
    "plate_with_hole",
    "wavy_two_body",
    "hertz",
    "hertz_piezo",
    "block3d",
    "rigid_foundation_extruded",
    "paper_two_body_extruded",
    "spherical_cap",
    "block3d_liftoff",
    "coulomb_strip3d",
    "bracket3d",
)
# Scenes whose Newton iteration stops just below TOL, one (quadratic) step short of rounding
# (block3d level 0: residuals 7.8e-7, 9.1e-13 (stop), 4.9e-16; bracket3d level 0: 7.7e-14 at the
# stop, κ 1.7e3), so that their derived tolerance would exceed the 1e-8 rounding bound of
# test_regression (7.5e-8, 2.7e-7): they are solved to TIGHT_TOL, which takes the next step to
# rounding (4.4e-16, 9.6e-16; derived tolerances 7.3e-11, 4.9e-9).
ONE_STEP_SHORT = ("block3d", "bracket3d")
TIGHT_TOL = 1e-14
TOL = 1e-12  # Newton's stopping tolerance: it converges quadratically to rounding below it
SAFETY = 1e3
EPS = float(np.finfo(float).eps)
RESIDUES = {
    "imbalance",
    "lemma_4_2",
    "complementarity",
    "mortar_patch_defect",
    "gap",
    "law_defect",  # the electrical contact law at the answer (electrical_contact.report)
    # the smallest gap − u_n over the contact nodes: 0 up to the rounding of that difference
    # wherever a node touches (every shipped unilateral scene; hertz_piezo stores −2.2e-19), so
    # compared relative to itself it is machine noise; the open/stick/slip counts are compared
    "min_gap",
    # contact3d's independent checks and frame defects (zero in exact arithmetic)
    "checks",
    "orthonormality_defect",
    "handedness_defect",
}
# file names, messages, contact.csv rows (their norms count), the electrical fixed point's
# record (times, and its last ‖Δk‖ at rounding level)
SKIP = {"files", "warnings", "table", "fixed_point"}


def levels(name: str) -> tuple[int, ...]:
    """The levels scene `name` is compared at."""
    return (0,) if name in LEVEL_0_ONLY else LEVELS


def scenes() -> list[str]:
    """Names of the shipped scenes."""
    return sorted(p.stem for p in SCENES_DIR.glob("*.toml"))


def _strip(value):
    """The postprocess summary without rounding residues and file lists (nested dicts kept).
    An insulated contact (electrical law "none": D·n = 0 there) has a flux_max that is the
    rounding of that zero (hertz_piezo level 0: 7.6e-16 in the baseline, 6.1e-16 on another
    machine), a residue like law_defect; with a conducting law it is an answer, compared."""
    if isinstance(value, dict):
        residues = RESIDUES | SKIP | ({"flux_max"} if value.get("kind") == "none" else set())
        return {k: _strip(v) for k, v in value.items() if k not in residues}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def run_case(name: str, level: int, overrides: tuple[str, ...] = ()) -> dict:
    """Build, solve (ssn, cold start, tol TOL; TIGHT_TOL for ONE_STEP_SHORT) and post-process one
    scene at one level. A scene with a [load_path] is solved step by step
    (`problems.pipeline.load_path`, every step cold); its last step is the case, and the norms
    of u and λ of every step are compared too (summary "steps"), with the largest residual and
    condition estimate over the steps."""
    scene = load_scene(name, list(overrides))
    plugin = registry.for_scene(scene)
    steps = None
    if scene.validated(plugin.SCENE_MODEL).load_path is not None:
        model, sol, steps = _path(scene, level)
    else:
        model = plugin.build(scene, level)
        tol = TIGHT_TOL if name in ONE_STEP_SHORT else TOL
        sol = solve_model(plugin, model, method="ssn", tol=tol, estimate_condition=True)
    vi = model.vi  # a plug-in's own solve may replace it (electrical contact: the last frozen VI)
    with tempfile.TemporaryDirectory() as tmp:
        extras = plugin.postprocess(model, sol, Path(tmp))
    fields = model.unknown_fields() if hasattr(model, "unknown_fields") else {"u": slice(None)}
    norms = {f"u:{k}": float(np.linalg.norm(sol.u[mask])) for k, mask in fields.items()}
    norms["lambda"] = float(np.linalg.norm(sol.lam))
    norms["energy"] = float(sol.u @ (vi.A @ sol.u))
    norms["slack"] = float(np.linalg.norm(vi.B @ sol.u - vi.gap)) if vi.m else 0.0
    summary = json.loads(json.dumps(_strip(extras), default=_jsonable))
    residual, condition = sol.residual, sol.info.get("condition_estimate") or 0.0
    if steps is not None:
        summary["steps"] = [{k: s[k] for k in ("t", "u", "lambda")} for s in steps]
        residual = max(s["residual"] for s in steps)
        condition = max(s["condition"] for s in steps)
    return {
        "plugin": plugin.NAME,
        "level": int(model.level),
        "dofs": {k: int(v) for k, v in model.dofs.items()},
        "norms": norms,
        "summary": summary,
        "converged": bool(sol.converged) and all(s["converged"] for s in steps or []),
        "residual": float(residual),
        "condition": float(condition),
        # the size of the terms that cancel in Bu − gap: the rounding scale of norms.slack
        "slack_scale": float(np.linalg.norm(abs(vi.B) @ abs(sol.u)) + np.linalg.norm(vi.gap))
        if vi.m
        else 0.0,
    }


def _path(scene, level: int):
    """The load path of `scene` at `level`: the last step's model and solution, and per step
    t, ‖u‖, ‖λ‖, residual, condition estimate and converged."""
    from problems.pipeline import validated
    from problems.pipeline.load_path import solve_path

    steps, last = [], {}

    def keep(step):
        sol = step.solution
        last.update(model=step.model, sol=sol)
        steps.append(
            {
                "t": float(step.t),
                "u": float(np.linalg.norm(sol.u)),
                "lambda": float(np.linalg.norm(sol.lam)),
                "residual": float(sol.residual),
                "condition": float(sol.info.get("condition_estimate") or 0.0),
                "converged": bool(sol.converged),
            }
        )

    solve_path(validated(scene), level, "ssn", TOL, cold=True, on_step=keep)
    return last["model"], last["sol"], steps


def _jsonable(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON-able: {type(x).__name__}")


def tolerance(base: dict, now: dict) -> float:
    """SAFETY · κ · (r₀ + r₁ + 4ε): the relative distance two converged runs may have."""
    kappa = max(base["condition"], now["condition"], 1.0)
    return SAFETY * kappa * (base["residual"] + now["residual"] + 4 * EPS)


def _numbers(x) -> bool:
    return isinstance(x, list) and bool(x) and all(isinstance(v, float) for v in x)


def compare(base, now, rtol: float, path: str = "") -> list[str]:
    """Differences of `now` from `base` beyond `rtol` (floats) or at all (the rest)."""
    if isinstance(base, dict) and isinstance(now, dict):
        out = [f"{path}.{k}: missing" for k in base if k not in now]
        out += [f"{path}.{k}: new entry" for k in now if k not in base]
        for k in base.keys() & now.keys():
            out += compare(base[k], now[k], rtol, f"{path}.{k}")
        return out
    if isinstance(base, float) or _numbers(base):
        a, b = np.atleast_1d(np.asarray(base, float)), np.atleast_1d(np.asarray(now, float))
        if a.shape != b.shape:
            return [f"{path}: shape {a.shape} → {b.shape}"]
        if not np.all(np.isfinite(b)):
            return [f"{path}: {now} is not finite"]
        size = max(float(np.linalg.norm(a)), float(np.linalg.norm(b)))
        diff = float(np.linalg.norm(a - b))
        if diff > rtol * size:
            return [
                f"{path}: {base} → {now} (relative {diff / max(size, 1e-300):.1e} > {rtol:.0e})"
            ]
        return []
    if isinstance(base, list) and isinstance(now, list):  # e.g. a load path's steps: each entry
        if len(base) != len(now):  # compared as above, its floats to rtol, never exactly
            return [f"{path}: {len(base)} entries → {len(now)}"]
        return [
            d
            for i, (a, b) in enumerate(zip(base, now, strict=True))
            for d in compare(a, b, rtol, f"{path}[{i}]")
        ]
    return [] if base == now else [f"{path}: {base!r} → {now!r}"]


def check_case(name: str, level: int, base: dict, now: dict) -> list[str]:
    """Every difference of one (scene, level) from its baseline, each naming where."""
    if not now["converged"]:
        return [f"{name} level {level}: did not converge (residual {now['residual']:.1e})"]
    rtol = tolerance(base, now)
    keep = ("plugin", "level", "dofs", "norms", "summary")
    # the baseline stripped too: a quantity that became a residue after it was stored
    old, new = _strip({k: base[k] for k in keep}), {k: now[k] for k in keep}
    # Bu − gap is a difference: a slack that is zero up to rounding is compared at the scale of
    # the terms that cancel (slack_scale), not relative to its own rounding-sized value
    a, b = old["norms"].get("slack"), new["norms"].get("slack")
    if a is not None and b is not None:
        if abs(a - b) <= rtol * max(a, b, now.get("slack_scale", 0.0)):
            old["norms"] = {k: v for k, v in old["norms"].items() if k != "slack"}
            new["norms"] = {k: v for k, v in new["norms"].items() if k != "slack"}
    return [f"{name} level {level}: {d}" for d in compare(old, new, rtol)]


def baseline(name: str) -> dict:
    """The stored baseline of one scene: {"0": case, "1": case}."""
    return json.loads((BASELINES / f"{name}.json").read_text())


def main(argv: list[str] | None = None) -> int:
    """0: every case matches its baseline (or --write stored them); 1: differences listed."""
    p = argparse.ArgumentParser(
        prog="python -m tests.regression", description=__doc__.split("\n")[0]
    )
    p.add_argument("--write", action="store_true", help="store the current answers as baselines")
    p.add_argument("--levels", default=None, help="comma-separated (default: levels(scene))")
    p.add_argument("--scenes", default=None, help="comma-separated names (default: all shipped)")
    args = p.parse_args(argv)
    names = args.scenes.split(",") if args.scenes else scenes()
    bad = []
    for name in names:
        chosen = [int(v) for v in args.levels.split(",")] if args.levels else levels(name)
        cases = {str(lev): run_case(name, lev) for lev in chosen}
        if args.write:
            BASELINES.mkdir(exist_ok=True)
            stored = baseline(name) if (BASELINES / f"{name}.json").exists() else {}
            stored.update(cases)
            (BASELINES / f"{name}.json").write_text(json.dumps(stored, indent=1) + "\n")
            print(f"wrote {BASELINES / name}.json (levels {list(cases)})")
            continue
        for lev, now in cases.items():
            diffs = check_case(name, int(lev), baseline(name)[lev], now)
            tol = tolerance(baseline(name)[lev], now)
            print(f"{name:<24} level {lev}: {'ok' if not diffs else 'DIFFERS'} (rtol {tol:.1e})")
            bad += diffs
    for d in bad:
        print("  " + d)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
