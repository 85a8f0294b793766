"""Uniform refinement of structured 2D and 3D meshes (`fem.refine.refine`).

    python benchmarks/bench_refine.py [--json FILE] [--overwrite]

For each cell type, in a fresh process: a structured mesh (`fem.meshing.rectangle` / `box`)
refined `times` times; the best CPU time (process_time) of 3 refinements, the cells made, and
the process's peak memory. Prints a table and writes the rows as JSON (default
bench_refine.json; an existing file is replaced only with --overwrite). CPU time, since the
machine may be shared.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

try:  # python -m benchmarks.NAME, or imported
    from .runner import record
except ImportError:  # python benchmarks/NAME.py
    from runner import record

CASES = [  # (cell type, cells per direction, refinements)
    ("triangle", 64, 3),
    ("quad", 64, 3),
    ("tetra", 8, 2),
    ("hexahedron", 8, 2),
]


def _case(cell_type: str, n: int, times: int, q) -> None:
    from fem.meshing import box, rectangle
    from fem.refine import refine
    from problems.commands.resources import peak_rss

    if cell_type in ("triangle", "quad"):
        mesh = rectangle((0.0, 1.0), (0.0, 1.0), (n, n), cell_type)
    else:
        mesh = box((0.0, 1.0), (0.0, 1.0), (0.0, 1.0), (n, n, n), cell_type)
    best = float("inf")
    for _ in range(3):
        t0 = time.process_time()
        fine = refine(mesh, times)
        best = min(best, time.process_time() - t0)
    q.put(
        {
            "cell_type": cell_type,
            "coarse_cells": mesh.n_cells,
            "times": times,
            "fine_cells": fine.n_cells,
            "fine_nodes": fine.n_nodes,
            "refine_s": best,
            "peak_mib": peak_rss() / 2**20,
        }
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default="bench_refine.json", help="where to write the rows")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --json")
    args = parser.parse_args(argv)
    if Path(args.json).exists() and not args.overwrite:
        parser.error(f"--json {args.json!r} exists; pass --overwrite to replace it, or a new path")
    rows = []
    head = ("cell type", "coarse", "times", "fine cells", "s", "MiB")
    print("{:12s} {:>8s} {:>5s} {:>10s} {:>7s} {:>7s}".format(*head))
    for case in CASES:
        row = record(_case, case)
        rows.append(row)
        print(
            f"{row['cell_type']:12s} {row['coarse_cells']:8d} {row['times']:5d} "
            f"{row['fine_cells']:10d} {row['refine_s']:7.3f} {row['peak_mib']:7.1f}"
        )
    with open(args.json, "w") as f:
        json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
