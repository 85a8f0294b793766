"""`mixvi bench`: speed of the nonlinear solve against one linear solve, measured in one run.

For each (scene, level) a child process builds the model and times
- the nonlinear solve: semismooth Newton with nested iteration (levels 0 … L solved in turn,
  each warm-started from the coarser one; the coarse levels' time is included), and the
  conic and homotopy paths where asked;
- one linear solve of the same matrix size: the stick limit (every multiplier Free, i.e. the
  tied problem), by the same machinery (ssn on a linear problem = one condensed factorisation
  and solve);
and reports their ratio and the child's peak resident memory (ru_maxrss, which — unlike
tracemalloc — includes the sparse factorisations' C allocations).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

import vi_core
from problems.errors import SceneError
from vi_core import Free, MixedVI
from vi_core.linalg import resolve_backend

from .options import level_range

DEFAULT = {"paper_two_body": (2, 5), "rigid_foundation": (3, 6)}


def _nested_ssn(plugin, scene, level: int, tol: float):
    prev, iters, total = None, [], 0.0
    for lev in range(level + 1):
        model = plugin.build(scene, lev)
        t = time.perf_counter()
        kw = plugin.warm_start(*prev, model) if prev else {}
        sol = vi_core.solve(model.vi, "ssn", tol=tol, **kw)
        total += time.perf_counter() - t
        iters.append(sol.iterations)
        prev = (model, sol)
    return prev[0], prev[1], total, iters


def _record(scene_name: str, level: int, solvers: list[str], tol: float, queue) -> None:
    from problems.plugins import registry
    from problems.scene import load_scene

    scene = load_scene(scene_name)
    plugin = registry.for_scene(scene)
    out = []
    # warm-up (untimed): library loading and first-call costs must not land on either timing
    for backend in ("splu", "auto"):
        vi_core.solve(plugin.build(scene, 0).vi, "ssn", tol=tol, linear_solver=backend)
    model, sol, t_nl, iters = _nested_ssn(plugin, scene, level, tol)
    vi = model.vi
    tied = MixedVI(A=vi.A, B=vi.B, f=vi.f, Lambda=Free(vi.m), gap=vi.gap)
    t = time.perf_counter()
    lin = vi_core.solve(tied, "ssn", tol=tol)
    t_lin = time.perf_counter() - t
    assert lin.iterations == 1 and lin.converged
    base = {"scene": scene_name, "level": level, "unknowns": vi.n + vi.m}
    out.append(
        {
            **base,
            "solver": "ssn",
            "iterations": sol.iterations,
            "iterations_per_level": iters,
            "converged": sol.converged,
            "time_nonlinear_s": t_nl,
            "time_linear_s": t_lin,
            "ratio": t_nl / t_lin,
        }
    )
    for meth in solvers:
        if meth == "ssn" or (meth == "conic" and vi.structure == "general"):
            continue
        s = vi_core.solve(vi, meth, tol=tol)
        out.append(
            {
                **base,
                "solver": meth,
                "iterations": s.iterations,
                "converged": s.converged,
                "time_nonlinear_s": s.time,
                "time_linear_s": t_lin,
                "ratio": s.time / t_lin,
                "difference_to_ssn": float(
                    np.linalg.norm(s.u - sol.u) / max(np.linalg.norm(sol.u), 1e-300)
                ),
            }
        )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux → MiB
    for r in out:
        r["peak_mem_mb"] = peak
    queue.put(out)


def bench_main(argv: list[str] | None = None) -> int:
    """Entry point of `mixvi bench` (prints a table, writes bench.json)."""
    p = argparse.ArgumentParser(prog="mixvi bench", description=__doc__.splitlines()[0])
    p.add_argument("--scenes", default=",".join(DEFAULT), help="comma-separated scene names")
    p.add_argument("--levels", default=None, help="A..B for every scene (default per scene)")
    p.add_argument("--solvers", default="ssn", help="comma-separated: ssn,conic,homotopy")
    p.add_argument("--tol", type=float, default=1e-10)
    p.add_argument("--out", default="bench.json")
    args = p.parse_args(argv)
    try:
        solvers = [s for s in args.solvers.split(",") if s]
        bad = [s for s in solvers if s not in ("ssn", "conic", "homotopy")]
        if bad:
            raise SceneError("--solvers", bad[0], "a comma-separated subset of ssn,conic,homotopy")
        jobs = []
        for name in [s for s in args.scenes.split(",") if s]:
            if args.levels:
                levels = level_range(args.levels)
            else:
                a, b = DEFAULT.get(name, (0, 3))
                levels = list(range(a, b + 1))
            jobs += [(name, lev) for lev in levels]
        from problems.scene import find_scene

        for name, _ in jobs:
            find_scene(name)
    except SceneError as err:
        print(f"mixvi: error: {err}", file=sys.stderr)
        return 2
    records = []
    print(
        f"{'scene':<18}{'level':>6}{'unknowns':>10}{'solver':>10}{'iter':>6}"
        f"{'nonlinear [s]':>15}{'linear [s]':>12}{'ratio':>8}{'peak [MB]':>11}"
    )
    ctx = mp.get_context("spawn")
    for name, lev in jobs:
        q = ctx.Queue()
        proc = ctx.Process(target=_record, args=(name, lev, solvers, args.tol, q))
        proc.start()
        recs = q.get()
        proc.join()
        for r in recs:
            print(
                f"{r['scene']:<18}{r['level']:>6}{r['unknowns']:>10}{r['solver']:>10}"
                f"{r['iterations']:>6}{r['time_nonlinear_s']:>15.2f}{r['time_linear_s']:>12.2f}"
                f"{r['ratio']:>8.2f}{r['peak_mem_mb']:>11.0f}",
                flush=True,
            )
        records += recs
    machine = {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cpus": mp.cpu_count(),
        "linear_solver": resolve_backend("auto"),
    }
    Path(args.out).write_text(json.dumps({"machine": machine, "records": records}, indent=2))
    print(f"wrote {args.out}")
    return 0
