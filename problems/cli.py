"""The `mixvi` command line.

mixvi solve [SCENE] [--level N] [--solver NAME] [--tol T] [--set key=value ...] [--out DIR]
mixvi scenes
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import vi_core

from . import registry
from .errors import SceneError
from .scene import SCENES_DIR, load_scene

DEFAULT_SCENE = "paper_two_body"
AGREE = 1e-6  # `mixvi check`: largest allowed relative difference between methods


MAX_LEVEL = 12
# --accuracy presets: (level, tol); measured time and error on the paper scene in the README
ACCURACY = {"fast": (1, 1e-6), "balanced": (2, 1e-8), "fine": (3, 1e-10)}
CONDITION_LIMIT = 200_000  # estimate the Newton matrix's condition up to this many unknowns


def _level(text: str) -> int:
    """argparse type: a refinement level 0 … MAX_LEVEL (exit 2 with a message otherwise)."""
    try:
        v = int(text)
    except ValueError:
        v = -1
    if not 0 <= v <= MAX_LEVEL:
        raise argparse.ArgumentTypeError(f"{text!r}: a level is an integer from 0 to {MAX_LEVEL}")
    return v


def _tol(text: str) -> float:
    """argparse type: a relative residual tolerance in (0, 1)."""
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not 0.0 < v < 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: a tolerance is a number in (0, 1)")
    return v


@contextmanager
def atomic_output(out: Path) -> Iterator[Path]:
    """Yield a temporary directory beside `out`; on success it replaces `out`, on any
    exception it is removed, so a half-written output directory never appears."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if out.exists():
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        out.rename(old)
    tmp.rename(out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _scaling_summary(model) -> dict:
    """The equilibration scales per field (geometric means): u = s_u·u', λ = s_λ·λ'."""
    sc = model.vi.scaling

    def gmean(v):
        return float(np.exp(np.mean(np.log(v)))) if v.size else None

    out = {"note": "u = s_u u', lambda = s_lam lambda' (Jacobi equilibration, geometric means)"}
    fields = model.unknown_fields() if hasattr(model, "unknown_fields") else {"u": slice(None)}
    for name, mask in fields.items():
        out[f"s_{name}"] = gmean(sc.s_u[mask])
    out["s_multiplier"] = gmean(sc.s_lam)
    return out


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


def cmd_solve(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    if args.accuracy is not None:  # a preset fills in what was not given explicitly
        level, tol = ACCURACY[args.accuracy]
        args.level = level if args.level is None else args.level
        args.tol = tol if args.tol is None else args.tol
    scene, plugin, model = _build(args)
    t_build = time.perf_counter() - t0
    method = args.solver or model.options.get("method", "ssn")
    if method not in vi_core.METHODS:
        raise SceneError("--solver", method, "one of " + ", ".join(vi_core.METHODS))
    tol = args.tol if args.tol is not None else model.options.get("tol", 1e-10)
    nested = []
    warm = {}
    if method == "ssn" and hasattr(plugin, "warm_start") and model.level > 0 and not args.cold:
        # nested iteration: solve levels 0 … L−1 first, each warm-starting the next
        prev = None
        for lev in range(model.level):
            coarse = plugin.build(scene, lev)
            kw = plugin.warm_start(*prev, coarse) if prev else {}
            csol = vi_core.solve(coarse.vi, method="ssn", tol=tol, **kw)
            nested.append({"level": lev, "iterations": csol.iterations, "time_s": csol.time})
            prev = (coarse, csol)
        warm = plugin.warm_start(*prev, model)
    if method == "ssn" and model.vi.n <= CONDITION_LIMIT:
        warm["estimate_condition"] = True
    sol = vi_core.solve(model.vi, method=method, tol=tol, **warm)
    if nested:
        nested.append({"level": model.level, "iterations": sol.iterations, "time_s": sol.time})
    out = Path(args.out) if args.out else Path("out") / scene.name
    with atomic_output(out) as tmp:
        extras = plugin.postprocess(model, sol, tmp)
        summary = {
            "scene": scene.name,
            "scene_file": scene.path,
            "plugin": plugin.NAME,
            "level": model.level,
            "solver": method,
            "tol": tol,
            "dofs": model.dofs,
            "converged": sol.converged,
            "iterations": sol.iterations,
            "residual": sol.residual,
            "residual_history": sol.history,
            **extras,
            "scaling": _scaling_summary(model),
            "condition_estimate": sol.info.get("condition_estimate"),
            "solver_info": sol.info,
            "warnings": model.warnings + sol.warnings + extras.get("warnings", []),
            "nested": nested,
            "time_s": {
                "build": t_build,
                "solve": sum(r["time_s"] for r in nested) if nested else sol.time,
                "total": time.perf_counter() - t0,
            },
        }
        (tmp / "summary.json").write_text(json.dumps(_jsonable(summary), indent=2) + "\n")
    c = summary.get("contact", {})
    print(
        f"{scene.name} level {model.level}: {sum(model.dofs.values())} unknowns "
        f"{model.dofs}, solver {method}"
    )
    identity = ""
    if "lemma_4_2" in summary:
        identity = f", lemma 4.2 gap {summary['lemma_4_2']:.1e}"
    elif "complementarity" in summary:
        identity = f", complementarity defect {summary['complementarity']:.1e}"
    print(
        f"  converged {sol.converged} in {sol.iterations} iterations, "
        f"residual {sol.residual:.2e}{identity}"
    )
    if nested:
        its = ", ".join(f"L{r['level']}: {r['iterations']}" for r in nested)
        print(f"  nested iteration (Newton steps per level, each warm-started): {its}")
    if c:
        print(f"  contact nodes {c['nodes']}: stick {c['stick']}, slip {c['slip']}")
    print(f"  time {summary['time_s']['total']:.2f} s; wrote {out}/")
    for w in summary["warnings"]:
        print(f"  warning: {w}")
    return 0 if sol.converged else 1


def _build(args: argparse.Namespace):
    scene = load_scene(args.scene or DEFAULT_SCENE, args.set or [])
    plugin = registry.for_scene(scene)
    return scene, plugin, plugin.build(scene, args.level)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def _levels(text: str | None, default: int | None) -> list[int | None]:
    if text is None:
        return [default]
    lo, sep, hi = text.partition("..")
    try:
        levels = list(range(int(lo), int(hi) + 1)) if sep else [int(lo)]
    except ValueError:
        raise SceneError("--levels", text, "a level N or a range A..B, e.g. 0..2") from None
    if not levels or min(levels) < 0 or max(levels) > MAX_LEVEL:
        raise SceneError(
            "--levels", text, f"a non-empty range of levels 0 … {MAX_LEVEL}, e.g. 0..2"
        )
    return levels


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
    scene = load_scene(args.scene or DEFAULT_SCENE, args.set or [])
    plugin = registry.for_scene(scene)
    records, ok = [], True
    for level in _levels(args.levels, args.level):
        conv, worst, rec = _check_level(scene, plugin, level, args.tol)
        ok = ok and conv and worst <= AGREE
        records.append(rec)
        print(
            f"{'agree' if conv and worst <= AGREE else 'DISAGREE'}: largest difference "
            f"{worst:.2e} (allowed {AGREE:g})"
        )
    if args.json:
        Path(args.json).write_text(
            json.dumps(_jsonable({"scene": scene.name, "records": records}), indent=2)
        )
    return 0 if ok else 1


def cmd_figures(args: argparse.Namespace) -> int:
    from . import plots

    bounds = (1.5e8, 1.0e8, 0.6e8)
    probe = load_scene(args.scene or DEFAULT_SCENE, args.set or [])
    if not hasattr(registry.for_scene(probe), "contact_state"):
        raise SceneError(
            "scene.plugin",
            probe.data.get("scene", {}).get("plugin"),
            "a contact plug-in (figures compares friction bounds)",
        )
    states = []
    for g in bounds:
        scene = load_scene(args.scene or DEFAULT_SCENE, [*(args.set or []), f"contact.g={g!r}"])
        plugin = registry.for_scene(scene)
        model = plugin.build(scene, args.level)
        sol = vi_core.solve(model.vi, method="ssn")
        if not sol.converged:
            print(
                f"mixvi: g = {g:g} did not converge (residual {sol.residual:.2e})", file=sys.stderr
            )
            return 1
        states.append((g, plugin.contact_state(model, sol)))
        st = states[-1][1]
        print(f"g = {g:.2e}: stick {int((~st['slip']).sum())}, slip {int(st['slip'].sum())}")
    out = Path(args.out) if args.out else Path("out") / f"{scene.name}_figures"
    with atomic_output(out) as tmp:
        plots.friction_comparison(states, tmp / "fig_5_4.png", title=scene.name)
    print(f"wrote {out}/fig_5_4.png")
    return 0


def cmd_scenes(args: argparse.Namespace) -> int:
    """The shipped scenes, the installed plug-ins, and the scenes plug-ins ship themselves."""
    dirs = [SCENES_DIR]
    plugins = []
    for name in registry.names():
        try:
            plug = registry.get(name)
        except SceneError as err:
            plugins.append((name, f"(cannot be loaded: {err})"))
            continue
        plugins.append((name, getattr(plug, "DESCRIPTION", "")))
        extra = getattr(plug, "SCENES_DIR", None)
        if extra is not None and Path(extra) not in dirs:
            dirs.append(Path(extra))
    rows = []
    for d in dirs:
        for p in sorted(Path(d).glob("*.toml")):
            head = tomllib.loads(p.read_text()).get("scene", {})
            label = p.stem if d == SCENES_DIR else str(p)
            rows.append((label, head.get("plugin", "piezo_contact"), head.get("title", "")))
    w = max(len(r[0]) for r in rows)
    wp = max(len(r[1]) for r in rows)
    print("scenes:")
    for name, plugin, title in rows:
        print(f"  {name:<{w}}  {plugin:<{wp}}  {title}")
    print("plug-ins:")
    wn = max(len(n) for n, _ in plugins)
    for name, desc in plugins:
        print(f"  {name:<{wn}}  {desc}")
    return 0


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="mixvi", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("solve", help="solve a scene and write summary.json, VTU and PNG files")
    s.add_argument("scene", nargs="?", help=f"scene file or shipped name (default {DEFAULT_SCENE})")
    s.add_argument("--level", type=_level, default=None, help="refinement level (default: scene's)")
    s.add_argument("--solver", default=None, help="ssn (default) or another vi_core method")
    s.add_argument("--tol", type=_tol, default=None, help="relative residual (default 1e-10)")
    s.add_argument(
        "--accuracy",
        choices=list(ACCURACY),
        default=None,
        help="preset level and tolerance: "
        + ", ".join(f"{k} = level {lv}, tol {t:g}" for k, (lv, t) in ACCURACY.items()),
    )
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a scene value")
    s.add_argument("--out", default=None, help="output directory (default out/SCENE)")
    s.add_argument(
        "--cold",
        action="store_true",
        help="no nested iteration: start Newton from λ = 0 on the requested level only",
    )
    s.set_defaults(func=cmd_solve)
    sc = sub.add_parser("scenes", help="list the scenes that ship")
    sc.set_defaults(func=cmd_scenes)
    for name, fn, helptext in (
        ("check", cmd_check, "solve with every applicable method and compare"),
        ("figures", cmd_figures, "Fig. 5.4: multiplier and jump for g = 1.5e8, 1e8, 0.6e8"),
    ):
        c = sub.add_parser(name, help=helptext)
        c.add_argument("scene", nargs="?", help=f"scene (default {DEFAULT_SCENE})")
        c.add_argument("--level", type=_level, default=None)
        c.add_argument("--set", action="append", metavar="KEY=VALUE")
        if name == "check":
            c.add_argument("--tol", type=_tol, default=1e-10)
            c.add_argument("--levels", default=None, help="several levels, e.g. 0..2")
            c.add_argument("--json", default=None, help="also write the table as JSON")
        else:
            c.add_argument("--out", default=None)
        c.set_defaults(func=fn)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `mixvi` command; exit status 2 on bad input."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["bench"]:  # its own argument parser (benchmark options)
        from .bench import bench_main

        return bench_main(argv[1:])
    if argv[:1] == ["extremes"]:  # its own argument parser
        from .extremes import extremes_main

        return extremes_main(argv[1:])
    if argv[:1] == ["study"]:  # its own argument parser (study options)
        from .study import study_main

        return study_main(argv[1:])
    args = parser().parse_args(argv)
    try:
        return args.func(args)
    except SceneError as err:
        print(f"mixvi: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
