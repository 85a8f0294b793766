"""Snapshot and compare the contact plug-ins' answers, field by field, between two checkouts.

    python -m benchmarks.contact_regression snap DIR [--levels 0] [--scenes a,b]
    python -m benchmarks.contact_regression compare DIR NEWDIR [--rtol 1e-12]

`snap` solves every shipped scene whose plug-in is a contact one (2D and 3D: Tresca, Coulomb,
electrical, bilateral, load paths; the signorini scenes too, built by the 2D contact build) at
the given levels (ssn, cold start, tol 1e-12; a [load_path] step by step, its last step kept)
and stores per (scene, level) DIR/SCENE_LEVEL.npz: u, λ, the full vector (u and φ of every
body), and every array of the plug-in's `contact_state` (the per-node states among them), plus
DIR/SCENE_LEVEL.json: the written files with their column names (CSV header, VTU data array
names) and the keys of the postprocess summary (nested). `compare` lists every difference of
NEWDIR from DIR: floats beyond a relative `rtol` (of the array's norm), integers, booleans and
strings (the states) at all, any key or column name. Exit status 1 if there is one.

This is a stricter sibling of `python -m tests.regression` (which compares norms and summaries
against committed baselines): it compares the arrays themselves between two checkouts.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

from problems.pipeline import solve_model
from problems.plugins import registry
from problems.scene import SCENES_DIR, load_scene

CONTACT_PLUGINS = ("contact", "piezo_contact", "contact3d", "signorini")  # with the former names
TOL = 1e-12
TIGHT = {"block3d": 1e-14, "bracket3d": 1e-14}  # as tests.regression.ONE_STEP_SHORT


def contact_scenes() -> list[str]:
    """The shipped scenes of a contact plug-in."""
    out = []
    for p in sorted(SCENES_DIR.glob("*.toml")):
        head = tomllib.loads(p.read_text()).get("scene", {})
        if head.get("plugin", "piezo_contact") in CONTACT_PLUGINS:
            out.append(p.stem)
    return out


def _solve(name: str, level: int):
    scene = load_scene(name, [])
    plugin = registry.for_scene(scene)
    if scene.validated(plugin.SCENE_MODEL).load_path is not None:
        from problems.pipeline import validated
        from problems.pipeline.load_path import solve_path

        last: dict = {}
        steps: list = []

        def keep(step):
            last.update(model=step.model, sol=step.solution)
            steps.append(np.concatenate([step.solution.u, step.solution.lam]))

        solve_path(validated(scene), level, "ssn", TOL, cold=True, on_step=keep)
        return plugin, last["model"], last["sol"], steps
    model = plugin.build(scene, level)
    sol = solve_model(plugin, model, method="ssn", tol=TIGHT.get(name, TOL))
    return plugin, model, sol, []


def _columns(path: Path) -> list[str]:
    if path.suffix == ".csv":  # the first line that is not a "# …" comment
        lines = (ln for ln in path.read_text().splitlines() if not ln.startswith("#"))
        return next(lines, "").split(",")
    if path.suffix in (".vtu", ".vtp", ".pvd"):
        return sorted(set(re.findall(r'Name="([^"]+)"', path.read_text(errors="replace"))))
    return []


def _keys(value, prefix: str = "") -> list[str]:
    if isinstance(value, dict):
        return [k2 for k, v in value.items() for k2 in [f"{prefix}{k}", *_keys(v, f"{prefix}{k}.")]]
    return []


def snap_case(name: str, level: int, out: Path) -> None:
    """Solve one scene at one level and store its arrays and output names under `out`."""
    plugin, model, sol, steps = _solve(name, level)
    arrays = {"u": sol.u, "lam": sol.lam, "full": model.full(sol.u)}
    for i, s in enumerate(steps):
        arrays[f"step{i}"] = s
    if getattr(model, "contact", None) is not None and hasattr(model, "contact_state"):
        state = model.contact_state(sol)
    elif getattr(model, "contact", None) is not None:
        state = plugin.contact_state(model, sol)
    else:
        state = {}
    for k, v in state.items():
        a = np.asarray(v)
        arrays[f"state:{k}"] = a.astype(str) if a.dtype == object else a
    np.savez(out / f"{name}_{level}.npz", **arrays)
    with tempfile.TemporaryDirectory() as tmp:
        summary = plugin.postprocess(model, sol, Path(tmp))
        files = {p.name: _columns(p) for p in sorted(Path(tmp).rglob("*")) if p.is_file()}
    (out / f"{name}_{level}.json").write_text(
        json.dumps({"files": files, "summary_keys": _keys(summary)}, indent=1) + "\n"
    )


def compare(old: Path, new: Path, rtol: float) -> list[str]:
    """Every difference of the snapshot `new` from `old`."""
    bad = []
    for f in sorted(old.glob("*.npz")):
        g = new / f.name
        if not g.exists():
            bad.append(f"{f.stem}: missing")
            continue
        a, b = np.load(f), np.load(g)
        if set(a.files) != set(b.files):
            bad.append(f"{f.stem}: arrays {sorted(set(a.files) ^ set(b.files))} differ")
        for k in sorted(set(a.files) & set(b.files)):
            x, y = a[k], b[k]
            if x.shape != y.shape:
                bad.append(f"{f.stem} {k}: shape {x.shape} -> {y.shape}")
            elif x.dtype.kind == "f":
                size = max(np.linalg.norm(np.nan_to_num(x)), np.linalg.norm(np.nan_to_num(y)))
                same_nan = np.array_equal(np.isnan(x), np.isnan(y))
                d = np.linalg.norm(np.nan_to_num(x - y))
                if not same_nan or d > rtol * max(size, 1e-300):
                    bad.append(f"{f.stem} {k}: relative {d / max(size, 1e-300):.1e}")
            elif not np.array_equal(x, y):
                bad.append(f"{f.stem} {k}: {np.sum(x != y)} entries differ")
        ja = json.loads(f.with_suffix(".json").read_text())
        jb = json.loads(g.with_suffix(".json").read_text())
        if ja != jb:
            bad.append(f"{f.stem}: files/columns/summary keys differ: {ja} -> {jb}")
    return bad


def main(argv: list[str] | None = None) -> int:
    """snap or compare (module docstring)."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.contact_regression")
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("snap")
    s.add_argument("dir", type=Path)
    s.add_argument("--levels", default="0")
    s.add_argument("--scenes", default=None)
    c = sub.add_parser("compare")
    c.add_argument("old", type=Path)
    c.add_argument("new", type=Path)
    c.add_argument("--rtol", type=float, default=1e-12)
    args = p.parse_args(argv)
    if args.cmd == "snap":
        args.dir.mkdir(parents=True, exist_ok=True)
        names = args.scenes.split(",") if args.scenes else contact_scenes()
        for name in names:
            for lev in (int(v) for v in args.levels.split(",")):
                snap_case(name, lev, args.dir)
                print(f"{name} level {lev}: stored", flush=True)
        return 0
    bad = compare(args.old, args.new, args.rtol)
    for b in bad:
        print(b)
    print(f"{len(bad)} differences")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
