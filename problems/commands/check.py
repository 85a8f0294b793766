"""`mixvi check`: solve with every applicable method and compare the answers."""

from __future__ import annotations

import argparse
import json

import numpy as np

import vi_core
from problems.output.files import jsonable, output_file
from problems.plugins import registry
from problems.scene import load_scene

from . import options, resources
from .options import DEFAULT_SCENE

AGREE = 1e-6  # largest allowed relative difference between methods


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def _check_level(scene, plugin, level, tol) -> tuple[bool, float, dict]:
    model = plugin.build(scene, level)
    vi = model.vi
    methods = ["ssn", "homotopy"] + (["conic"] if vi.structure != "general" else [])
    print(f"\n{scene.name} level {model.level}: n = {vi.n}, m = {vi.m}, A {vi.structure}")
    print(f"{'method':<10}{'converged':>10}{'iter':>6}{'residual':>11}{'time [s]':>10}")
    sols = {}
    for meth in methods:
        sol = vi_core.solve(vi, method=meth, tol=tol)
        sols[meth] = sol
        print(
            f"{meth:<10}{sol.converged!s:>10}{sol.iterations:>6}{sol.residual:>11.2e}"
            f"{sol.time:>10.2f}"
        )
    print(f"{'pair':<20}{'|Δu|/|u|':>12}{'|Δλ|/|λ|':>12}")
    worst = 0.0
    for i, a in enumerate(methods):
        for b in methods[i + 1 :]:
            du = _rel(sols[a].u, sols[b].u)
            dl = _rel(sols[a].lam, sols[b].lam) if vi.m else 0.0
            worst = max(worst, du, dl)
            print(f"{a + ' / ' + b:<20}{du:>12.2e}{dl:>12.2e}")
    polish = sols["conic"].info.get("polish") if "conic" in sols else None
    if polish:
        print(
            f"conic: Clarabel's own answer had residual {polish['residual_before']:.2e}; "
            f"{polish['steps']} Newton polish step(s) moved it by {polish['relative_change']:.2e}"
        )
    h = sols["homotopy"].info
    rates = h.get("rates") or [float("nan")]
    bound = h.get("rate_bound", float("nan"))
    rho, t0 = h.get("rho", float("nan")), h.get("t0_paper", float("nan"))
    t0_text = f"{t0:.2e}" if isinstance(t0, float) else str(t0)
    if bound > 0 and h.get("rates"):
        contraction = (
            f"observed contraction {rates[-1]:.4f} vs (s - tau) rho = {bound:.4f} "
            f"(ratio {rates[-1] / bound:.2f})"
        )
    else:
        contraction = "symmetric A: one level-0 solve, no fixed-point iteration"
    print(
        f"homotopy: rho = {rho:.4f}, levels {len(h.get('levels', [])) - 1}, {contraction}; "
        f"paper's t0 (3.11) = {t0_text}"
    )
    record = {
        "level": model.level,
        "unknowns": vi.n + vi.m,
        "structure": vi.structure,
        "methods": {
            k: {
                "converged": v.converged,
                "iterations": v.iterations,
                "residual": v.residual,
                "time_s": v.time,
            }
            for k, v in sols.items()
        },
        "max_difference": worst,
        "rho": h.get("rho"),
        "t0_paper": h.get("t0_paper"),
        "contraction_observed": rates[-1],
        "contraction_bound": bound,
    }
    return all(v.converged for v in sols.values()), worst, record


def cmd_check(args: argparse.Namespace) -> int:
    """Compare ssn, homotopy and conic per level; exit status 1 if they disagree."""
    scene = load_scene(args.scene or DEFAULT_SCENE, args.set or [])
    plugin = registry.for_scene(scene)
    if args.levels is not None:
        option, text = "--levels", args.levels
        a, b = options.level_range(args.levels)
    else:
        lev = args.level if args.level is not None else resources.default_level(plugin, scene)
        option, text, (a, b) = "--level", str(lev), (lev, lev)
    resources.check_levels(plugin, scene, (a, b), option, text, args.force)
    if args.json is None:
        return _check(scene, plugin, range(a, b + 1), args.tol, None)
    with output_file(args.json, "--json") as target:
        return _check(scene, plugin, range(a, b + 1), args.tol, target)


def _check(scene, plugin, levels, tol, target) -> int:
    records, ok = [], True
    for level in levels:
        conv, worst, rec = _check_level(scene, plugin, level, tol)
        ok = ok and conv and worst <= AGREE
        records.append(rec)
        print(
            f"{'agree' if conv and worst <= AGREE else 'DISAGREE'}: largest difference "
            f"{worst:.2e} (allowed {AGREE:g})"
        )
    if target is not None:
        target.write(json.dumps(jsonable({"scene": scene.name, "records": records}), indent=2))
    return 0 if ok else 1
