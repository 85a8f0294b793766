"""The memory guard's estimate against the solve it guards.

    python benchmarks/bench_estimate.py [--level L] [--json FILE] SCENE ...

For each scene (a shipped name or a .toml path), in a fresh process: the CPU time of
`resources.Sizes` (what `mixvi solve` runs before building, `check_levels`), then of building
and solving the level (`pipeline.solve` with the defaults; nested iteration included), the
ratio, and the process's peak memory. Prints a table and writes the rows as JSON (default
bench_estimate.json). CPU time (process_time), since the machine may be shared: a ratio of two
CPU times taken in one process is what to compare.
"""

from __future__ import annotations

import argparse
import json
import time

try:  # python -m benchmarks.NAME, or imported
    from .runner import record
except ImportError:  # python benchmarks/NAME.py
    from runner import record


def _case(scene_name: str, level: int, q) -> None:
    from problems import pipeline
    from problems.commands.resources import Sizes, peak_rss

    loaded = pipeline.load(scene_name)
    t0 = time.process_time()
    sizes = Sizes(loaded.plugin, loaded.scene)
    t1 = time.process_time()
    run = pipeline.solve(loaded, level)
    t2 = time.process_time()
    q.put(
        {
            "scene": scene_name,
            "level": level,
            "unknowns": sizes.unknowns(level),
            "estimate_s": t1 - t0,
            "solve_s": t2 - t1,
            "ratio": (t1 - t0) / (t2 - t1),
            "converged": bool(run.solution.converged),
            "peak_mib": peak_rss() / 2**20,
        }
    )


def main() -> None:
    """Run the cases, print the table, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--level", type=int, default=0)
    ap.add_argument("--json", default="bench_estimate.json")
    args = ap.parse_args()
    rows = []
    print(f"{'scene':<28} {'L':>2} {'unknowns':>9} {'estimate s':>10} {'solve s':>9} "
          f"{'ratio':>7} {'peak MiB':>9}")  # fmt: skip
    for name in args.scenes:
        r = record(_case, (name, args.level))
        rows.append(r)
        print(f"{r['scene'][-28:]:<28} {r['level']:>2} {r['unknowns']:>9,} "
              f"{r['estimate_s']:>10.2f} {r['solve_s']:>9.2f} {r['ratio']:>7.1%} "
              f"{r['peak_mib']:>9.0f}")  # fmt: skip
    with open(args.json, "w") as f:
        json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
