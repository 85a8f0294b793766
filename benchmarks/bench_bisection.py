"""Local refinement by newest-vertex bisection (`fem.bisection.refine_marked`) against
one uniform refinement of the same mesh (`fem.refine.refine`).

    python benchmarks/bench_bisection.py [--json FILE] [--overwrite] [--quick]

Meshes: structured triangles of [0, 1]² (`fem.meshing.rectangle`, 2·n² cells) and the graded
unstructured punch of tests/data/user_meshes refined uniformly to a size, both labelled once
(`fem.bisection.prepared`). Marks: a random fraction of the cells (0.01, 0.1, 1.0; seed 0). Each
case runs in a fresh process: the best CPU time (process_time) of 3 calls of `refine_marked` and
of `refine`, their ratio, and the peak memory each call allocates above what it is given
(tracemalloc, a separate call), with the process's peak resident memory (VmHWM). CPU time and
ratios taken in one process, since the machine may be shared. Prints a table and writes the
rows as JSON (default bench_bisection.json; an existing file is replaced only with --overwrite).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import time
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PUNCH = ROOT / "tests" / "data" / "user_meshes" / "meshes" / "punch_graded.msh"
FRACTIONS = (0.01, 0.1, 1.0)
# (mesh, size): structured n for 2n² cells; punch: uniform refinements of its 1,054 cells
CASES = [("structured", 71), ("structured", 224), ("structured", 708), ("punch", 3), ("punch", 5)]
QUICK = [("structured", 71), ("punch", 2)]


def _mesh(kind: str, size: int):
    from fem.bisection import prepared
    from fem.mesh_import import body_mesh, read_mesh
    from fem.meshing import rectangle
    from fem.refine import refine

    if kind == "structured":
        return prepared(rectangle((0.0, 1.0), (0.0, 1.0), (size, size), "triangle"))
    return prepared(refine(body_mesh(read_mesh(PUNCH), "punch"), size))


def _best(f, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        f()
        best = min(best, time.process_time() - t0)
    return best


def _peak(f) -> float:
    """MiB allocated at the peak of one call of f (tracemalloc: numpy's buffers included)."""
    tracemalloc.start()
    f()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def _case(kind: str, size: int, q) -> None:
    import numpy as np

    from fem.bisection import refine_marked
    from fem.refine import refine
    from problems.commands.resources import peak_rss

    mesh = _mesh(kind, size)
    uniform_s = _best(lambda: refine(mesh))
    uniform_mib = _peak(lambda: refine(mesh))
    rows = []
    for fraction in FRACTIONS:
        marked = np.random.default_rng(0).random(mesh.n_cells) < fraction
        fine, _ = refine_marked(mesh, marked)
        s = _best(lambda m=marked: refine_marked(mesh, m))
        rows.append(
            {
                "mesh": kind,
                "cells": mesh.n_cells,
                "marked": fraction,
                "new_cells": fine.n_cells,
                "bisection_s": s,
                "uniform_s": uniform_s,
                "ratio": s / uniform_s,
                "bisection_mib": _peak(lambda m=marked: refine_marked(mesh, m)),
                "uniform_mib": uniform_mib,
                "vmhwm_mib": peak_rss() / 2**20,
            }
        )
    q.put(rows)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default="bench_bisection.json", help="where to write the rows")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --json")
    parser.add_argument("--quick", action="store_true", help="two small meshes only")
    args = parser.parse_args(argv)
    if Path(args.json).exists() and not args.overwrite:
        parser.error(f"--json {args.json!r} exists; pass --overwrite to replace it, or a new path")
    ctx = mp.get_context("spawn")
    rows = []
    head = ("mesh", "cells", "marked", "new cells", "NVB s", "unif s", "ratio", "NVB MiB")
    print(
        "{:10s} {:>9s} {:>6s} {:>10s} {:>7s} {:>7s} {:>6s} {:>8s} {:>8s}".format(*head, "unif MiB")
    )
    for case in QUICK if args.quick else CASES:
        q = ctx.Queue()
        p = ctx.Process(target=_case, args=(*case, q))
        p.start()
        got = q.get()
        p.join()
        for r in got:
            print(
                f"{r['mesh']:10s} {r['cells']:9d} {r['marked']:6.2f} {r['new_cells']:10d} "
                f"{r['bisection_s']:7.3f} {r['uniform_s']:7.3f} {r['ratio']:6.2f} "
                f"{r['bisection_mib']:8.1f} {r['uniform_mib']:8.1f}"
            )
        rows += got
    with open(args.json, "w") as f:
        json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
