"""`mixvi extremes`: every plug-in's extreme rows (contract v2 `extremes()`), each checked.

Every row (a `contract.ExtremeRow`: a shipped scene, `--set`-style overrides, a level) is
built, solved with semismooth Newton and, where affordable, with the conic (Clarabel) and
homotopy methods (for a quasi-variational Λ — Coulomb or contact-only Tresca friction — with
the fixed point on Tresca problems instead, its Tresca problems solved by conic), and reports
- the relative natural-map residual and Newton steps of ssn,
- the largest relative difference of (u, λ) between ssn and the other methods' raw answers
  (conic without polishing),
- λ ∈ Λ: the distance of ssn's multiplier to Λ relative to ‖λ‖ (`admissibility`),
- the model's complementarity identity where it has one (`Model.complementarity`),
- the plug-in's own checks of the row (stick/slip counts, Lemma 4.2, homogeneity, locking, ...),
- a note that says what failed or what limitation shows, in plain words.

A row fails (exit status 1) when ssn does not reach RESIDUAL_OK, the methods disagree beyond
AGREE_OK, λ lies outside Λ beyond ADMISSIBLE_OK, or a plug-in check says FAIL.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import problems.pipeline as pipeline
import vi_core
from problems.errors import SceneError
from problems.output import signals
from problems.output.files import output_folder
from problems.plugins import registry
from problems.plugins.contract import ExtremeRow, needs, relative_difference
from vi_core.kkt import Checker

from . import options, resources

RESIDUAL_OK = 1e-8
AGREE_OK = 1e-6
ADMISSIBLE_OK = 1e-9
INACTIVE = 1e-12  # a part of (u', λ') below this × its size: rounding zero (`_difference`)
CONIC_MAX = 20_000  # unknowns: above this the conic method is skipped (time)
HOMOTOPY_MAX = 3_000  # unknowns: above this the homotopy method is skipped (time)


def _difference(model: Any, vi: Any, sol: vi_core.Solution, other: vi_core.Solution) -> float:
    """The largest relative difference between `other` and ssn's `sol`, per field: each field
    of u (displacement and potential apart, `Model.full_fields` where the model has them: metres
    and volts are not added; with the Dirichlet values, `Model.full`: the data's scale) and λ.
    A part that is (rounding) zero in ssn's answer — below INACTIVE of the answer's size
    ‖(u', λ')‖ in equilibrated variables — is measured relative to that size instead (a 0/0
    would call the 1e-12 of an interior-point λ, or of a glued u, a disagreement). `vi`: the
    problem ssn's answer solves (`pipeline.problem_at`), whose equilibration measures the
    difference."""
    checker = Checker.of(vi)
    u_s, lam_s = checker.scaled(sol.u, sol.lam)
    u_o, lam_o = checker.scaled(other.u, other.lam)
    size = max(float(np.linalg.norm(np.concatenate([u_s, lam_s]))), 1e-300)
    full = getattr(model, "full", lambda u: u)
    a_u, b_u = full(other.u), full(sol.u)
    if hasattr(model, "full_fields"):
        masks = [(f, f[model.free]) for f in model.full_fields().values()]
    else:
        masks = [(np.ones(a_u.size, dtype=bool), np.ones(u_s.size, dtype=bool))]
    parts = [(u_s[r], u_o[r], a_u[f], b_u[f]) for f, r in masks]
    parts.append((lam_s, lam_o, other.lam, sol.lam))
    diffs = []
    for s_, o_, a, b in parts:
        if s_.size == 0:
            continue
        active = np.linalg.norm(s_) > INACTIVE * size
        diffs.append(relative_difference(a, b) if active else float(np.linalg.norm(o_ - s_)) / size)
    return max(diffs, default=0.0)


def rows(plugins: dict[str, Any] | None = None) -> list[ExtremeRow]:
    """The rows of every plug-in that declares `extremes()` (all registered ones by default),
    each tagged with its plug-in's name."""
    plugins = registry.plugins() if plugins is None else plugins
    out = []
    for name, plugin in plugins.items():
        for row in plugin.extremes() if hasattr(plugin, "extremes") else ():
            out.append(dataclasses.replace(row, plugin=name))
    return out


def run_row(row: ExtremeRow) -> dict:
    """Solve one row with every affordable method (`pipeline.solve_model`: the scene's problem,
    with the plug-in's outer iteration, e.g. electrical contact) and collect the checks."""
    t0 = time.perf_counter()
    scene = row.load()
    plugin = registry.for_scene(scene)
    model = plugin.build(scene, row.level)
    sol = pipeline.solve_model(plugin, model, method="ssn")
    vi = pipeline.problem_at(plugin, model, sol)  # the problem ssn's answer must solve
    n = vi.n + vi.m
    rec: dict = {
        "row": row.name,
        "plugin": plugin.NAME,
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
    if vi.Lambda.quasi:  # Coulomb / contact-only Tresca: the fixed point on Tresca problems
        others.append("fixed_point")
    elif vi.structure != "general" and n <= CONIC_MAX:
        others.append("conic")
    if n <= HOMOTOPY_MAX and not vi.Lambda.quasi:
        others.append("homotopy")
    for meth in others:
        # raw answers: the conic one as Clarabel returns it (polishing would make it ssn's)
        opts = {"max_levels": 12} if meth == "homotopy" else {"polish": 0}
        if meth == "fixed_point":  # its Tresca problems by conic (homotopy for a general A)
            opts = {"inner": "conic" if vi.structure != "general" else "homotopy"}
        other = pipeline.solve_model(plugin, model, method=meth, **opts)
        rec["iterations"][meth] = other.iterations
        if meth == "homotopy":
            rec["rho"] = other.info.get("rho")
            rec["homotopy_levels"] = max(len(other.info.get("levels", [])) - 1, 0)
        failed = other.info.get("status") != "optimal" if meth == "conic" else not other.converged
        if failed:
            rec["notes"].append(f"{meth} did not converge (residual {other.residual:.1e})")
        rec["agreement"][meth] = _difference(model, vi, sol, other)
    lam = sol.lam
    rec["admissibility"] = (
        relative_difference(vi.Lambda.project(lam), lam) if vi.m and lam.any() else 0.0
    )
    if hasattr(model, "complementarity"):
        rec["complementarity"] = model.complementarity(sol)
    checked = []
    for check in row.checks:
        values, notes = check(plugin, row, model, sol)
        rec.update(values)
        checked += notes
    rec["warnings"] = model.warnings + sol.warnings
    rec["time_s"] = time.perf_counter() - t0
    rec["notes"] += _verdict(rec) + checked
    rec["ok"] = not any(x.startswith("FAIL") for x in rec["notes"])
    return rec


def _verdict(rec: dict) -> list[str]:
    """Plain-words judgement of the generic checks of a record against the thresholds."""
    notes = []
    if not rec["converged"] or rec["residual"] > RESIDUAL_OK:
        notes.append(f"FAIL: ssn residual {rec['residual']:.1e}")
    worst = max(rec["agreement"].values(), default=0.0)
    if worst > AGREE_OK:
        bad = ", ".join(f"{k} {v:.1e}" for k, v in rec["agreement"].items() if v > AGREE_OK)
        notes.append(f"FAIL: methods disagree ({bad})")
    if not rec["agreement"]:
        notes.append("ssn only (too large for conic/homotopy)")
    if rec["admissibility"] > ADMISSIBLE_OK:
        notes.append(f"FAIL: λ lies outside Λ by {rec['admissibility']:.1e} (relative)")
    if rec.get("complementarity") is not None and rec["complementarity"] > 1e-10:
        notes.append(f"complementarity defect {rec['complementarity']:.1e}")
    if "rho" in rec:
        notes.append(f"ρ = {rec['rho']:.2f}, {rec['homotopy_levels']} homotopy levels")
    return notes


def format_row(rec: dict) -> str:
    its = "/".join(str(v) for v in rec["iterations"].values())
    agree = max(rec["agreement"].values(), default=float("nan"))
    return (
        f"{rec['plugin']:<14}{rec['row']:<38}{rec['unknowns']:>8}{rec['residual']:>10.1e}"
        f"{agree:>10.1e}{its:>10}  {'; '.join(rec['notes'])}"
    )


HEADER = f"{'plugin':<14}{'row':<38}{'unknowns':>8}{'residual':>10}{'agree':>10}{'iters':>10}  note"


def extremes_main(argv: list[str]) -> int:
    """`mixvi extremes [--plugins A,B] [--huge] [--only TEXT] [--out DIR]`: 0 if every row
    passes, else 1."""
    p = argparse.ArgumentParser(prog="mixvi extremes", description=__doc__.splitlines()[0])
    p.add_argument(
        "--plugins", default=None, help="comma-separated plug-in names (default: every one)"
    )
    p.add_argument("--huge", action="store_true", help="include the huge rows (~1.6M unknowns)")
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
    names = registry.names()
    chosen = names if args.plugins is None else options.names(args.plugins, "--plugins", names)
    plugins = {}
    for n in chosen:  # a broken third-party plug-in is skipped, unless asked for by name
        try:
            plugins[n] = registry.get(n)
        except SceneError as err:
            if args.plugins is not None:
                raise
            print(f"mixvi: skipping plug-in {n!r}: {err}", file=sys.stderr)
    if args.plugins is not None:
        for plugin in plugins.values():
            needs(plugin, "mixvi extremes", "extremes")
    candidates = [r for r in rows(plugins) if args.huge or not r.huge]
    selected = [r for r in candidates if args.only is None or args.only in r.name]
    if not selected:
        raise SceneError(
            "--only",
            args.only,
            "text contained in a row name: " + "; ".join(r.name for r in candidates),
        )
    inputs = []  # the scene files the rows read
    for row in selected:  # every row's level must fit in memory before anything runs
        option = "--huge" if row.huge else "--only"
        plugin = plugins[row.plugin]
        scene = row.load()
        inputs += scene.files()
        resources.check_levels(plugin, scene, (row.level, row.level), option, row.name, args.force)
    with output_folder(args.out, "--out", overwrite=args.overwrite, inputs=inputs) as folder:
        print("iters = ssn/conic/homotopy; agree = largest relative difference to ssn")
        print(HEADER)
        records = []
        for row in selected:
            rec = signals.interruptible(run_row, row)  # a signal acts inside compiled code
            records.append(rec)
            print(format_row(rec), flush=True)
        with folder.staging() as tmp:
            text = json.dumps(records, indent=2, default=float) + "\n"
            (tmp / "extremes.json").write_text(text)
    print(f"wrote {Path(args.out) / 'extremes.json'}")
    return 0 if all(r["ok"] for r in records) else 1
