"""CPU time and peak memory of the vectorised assembly (`fem.assembly`).

    python benchmarks/bench_assembly.py [--level2 6] [--level3 4] [--repeat 3] [--json FILE]

For each cell type, in a fresh process: the unit square of 4 × 4 cells refined `level2` times
(quad; triangle: each square halved) or the unit cube of 2 × 2 × 2 cells at `level3`
(hexahedron; tetra: 6 per cube), then the best CPU time (process_time, of `repeat` runs) of the
elasticity, coupling, permittivity and mass matrices with BaTiO3's constants, and the process's
peak memory. Prints a table and writes the rows as JSON (default bench_assembly.json). CPU time
of one process, since the machine may be shared: compare ratios taken in one session.
"""

from __future__ import annotations

import argparse
import json
import time

try:  # python -m benchmarks.NAME, or imported
    from .runner import record
except ImportError:  # python benchmarks/NAME.py
    from runner import record

FORMS = ("elasticity", "coupling", "permittivity", "mass")


def _case(cell_type: str, level: int, repeat: int, q) -> None:
    import numpy as np

    from fem import assembly
    from fem.meshing import box, rectangle
    from fem.refine import refine
    from fem.tensors import NAMED, plane_strain
    from problems.commands.resources import peak_rss

    if cell_type in ("quad", "triangle"):
        mesh = refine(rectangle((0.0, 1.0), (0.0, 1.0), (4, 4), cell_type), level)
        m = plane_strain(NAMED["BaTiO3"], "xz")
    else:
        mesh = box((0.0, 1.0), (0.0, 1.0), (0.0, 1.0), (2, 2, 2), cell_type, level=level)
        m = NAMED["BaTiO3"]
    d = mesh.points.shape[1]
    calls = {
        "elasticity": lambda: assembly.elasticity_matrix(mesh, m.C),
        "coupling": lambda: assembly.coupling_matrix(mesh, m.e),
        "permittivity": lambda: assembly.permittivity_matrix(mesh, m.kappa),
        "mass": lambda: assembly.mass_matrix(mesh),
    }
    row = {"cell_type": cell_type, "level": level, "cells": mesh.n_cells, "dofs": d * mesh.n_nodes}
    for name in FORMS:
        best = np.inf
        for _ in range(repeat):
            t0 = time.process_time()
            calls[name]()
            best = min(best, time.process_time() - t0)
        row[f"{name}_s"] = best
    row["peak_mib"] = peak_rss() / 2**20
    q.put(row)


def main() -> None:
    """Run the cases, print the table, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--level2", type=int, default=6)
    ap.add_argument("--level3", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default="bench_assembly.json")
    args = ap.parse_args()
    rows = []
    print(f"{'cell type':<11} {'L':>2} {'cells':>8} {'dofs':>8} "
          + " ".join(f"{f + ' s':>14}" for f in FORMS) + f" {'peak MiB':>9}")  # fmt: skip
    for cell_type in ("quad", "triangle", "hexahedron", "tetra"):
        level = args.level2 if cell_type in ("quad", "triangle") else args.level3
        r = record(_case, (cell_type, level, args.repeat))
        rows.append(r)
        print(f"{r['cell_type']:<11} {r['level']:>2} {r['cells']:>8,} {r['dofs']:>8,} "
              + " ".join(f"{r[f + '_s']:>14.3f}" for f in FORMS)
              + f" {r['peak_mib']:>9.0f}")  # fmt: skip
    with open(args.json, "w") as f:
        json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
