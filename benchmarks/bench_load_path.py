"""Benchmark: a load path with every step rebuilt vs. updated (the plug-in's `update`).

    python benchmarks/bench_load_path.py [SCENE ...] [--levels 1 2 3] [--repeat 2]
        [--out FILE]

Solves each scene's [load_path] at each level `--repeat` times (default 2, alternating) each
way in one run, `solve_path(..., rebuild=True)` (every step built from the scene) and with the
plug-in's `update` (after the first step only the t-dependent data re-read), and prints for the
fastest run of each way: steps, wall time, build time (all steps, and the mean of the steps
after the first: the ones an update serves), the ratio of wall times,
the largest relative difference between the two runs' step answers (rounding only), and the
peak memory of the process (resource.getrusage, KiB → MiB; the maximum so far, so the larger of
the two runs). Writes the table as JSON (default bench_load_path.json in the current folder).
"""

from __future__ import annotations

import argparse
import resource
import sys
import time

import numpy as np

import problems.pipeline as pipeline
from problems.output.files import Output, claim
from problems.pipeline.load_path import solve_path

SCENES = ("shear_strip_path", "block3d_liftoff")


def _run(loaded: pipeline.Loaded, level: int, rebuild: bool) -> tuple[dict, list]:
    """(timings, per-step (u, λ)) of one solve of the path."""
    answers: list = []
    t0 = time.perf_counter()
    path = solve_path(
        loaded,
        level=level,
        rebuild=rebuild,
        on_step=lambda s: answers.append((s.solution.u.copy(), s.solution.lam.copy())),
    )
    wall = time.perf_counter() - t0
    builds = [r["time_s"]["build"] for r in path.steps]
    later = sum(builds[1:]) / max(len(builds) - 1, 1)  # steps an update can serve
    timings = {"wall_s": wall, "build_s": sum(builds), "later_build_s": later}
    return {**timings, "steps": len(builds)}, answers


def _difference(a: list, b: list) -> float:
    """The largest relative difference between the steps' answers of two runs."""
    worst = 0.0
    for pa, pb in zip(a, b, strict=True):
        for x, y in zip(pa, pb, strict=True):
            scale = max(float(np.abs(y).max(initial=0.0)), 1e-300)
            worst = max(worst, float(np.abs(x - y).max(initial=0.0)) / scale)
    return worst


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print the table, write the JSON."""
    p = argparse.ArgumentParser(prog="python benchmarks/bench_load_path.py")
    p.add_argument("scenes", nargs="*", default=list(SCENES))
    p.add_argument("--levels", type=int, nargs="+", default=[1, 2, 3])
    p.add_argument("--repeat", type=int, default=2, help="runs of each kind (the fastest kept)")
    p.add_argument("--out", default="bench_load_path.json")
    args = p.parse_args(argv)
    inputs = [f for name in args.scenes for f in pipeline.load(name).scene.files()]
    with claim([Output(args.out, "--out", "json")], inputs) as run:
        rows = []
        head = (
            f"{'scene':<18} {'lvl':>3} {'steps':>5} {'rebuild s':>10} {'update s':>9} "
            f"{'ratio':>6} {'build s (r/u)':>15} {'step 2+ build ms (r/u)':>22} "
            f"{'max rel diff':>12} {'peak MiB':>8}"
        )
        print(head)
        for name in args.scenes:
            loaded = pipeline.load(name)
            for level in args.levels:
                runs: dict[bool, list] = {True: [], False: []}
                for _ in range(args.repeat):  # alternating, so neither order gets the warm-up
                    for rebuild in (True, False):
                        runs[rebuild].append(_run(loaded, level, rebuild))
                full, a = min(runs[True], key=lambda r: r[0]["wall_s"])
                upd, b = min(runs[False], key=lambda r: r[0]["wall_s"])
                peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
                row = {
                    "scene": name,
                    "level": level,
                    "steps": full["steps"],
                    "rebuild": full,
                    "update": upd,
                    "ratio_wall": upd["wall_s"] / full["wall_s"],
                    "max_rel_difference": _difference(a, b) if len(a) == len(b) else None,
                    "peak_rss_mib": peak,
                }
                rows.append(row)
                diff = row["max_rel_difference"]
                print(
                    f"{name:<18} {level:>3} {full['steps']:>5} {full['wall_s']:>10.2f} "
                    f"{upd['wall_s']:>9.2f} {row['ratio_wall']:>6.2f} "
                    f"{full['build_s']:>7.2f}/{upd['build_s']:<7.2f} "
                    f"{1e3 * full['later_build_s']:>11.1f}/{1e3 * upd['later_build_s']:<10.1f} "
                    f"{'-' if diff is None else f'{diff:.1e}':>12} {peak:>8.0f}",
                    flush=True,
                )
        run.file("--out").write({"rows": rows})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
