"""Convergence of a Hertz scene to the closed form: one row per level (unknowns, Newton steps,
load P, half-width a and peak pressure p0 against Hertz at the measured load, their relative
errors and the observed rates between levels), printed and written as JSON.

    python benchmarks/hertz_table.py [--scene hertz] [--levels 0..3] [--radius 1.0]
        [--set KEY=VALUE ...] [--json FILE]

With `--set contact.electrical.kind='"grounded"'` on hertz_piezo the cylinder is a conducting
indenter and the reference E* the conducting one (`contact_references.hertz_modulus`).
"""

from __future__ import annotations

import argparse
import math
import sys

from benchmarks import hertz
from problems.output.files import Output, claim
from problems.pipeline import load, solve


def rows(scene: str, levels: range, R: float, overrides: list[str] = ()) -> list[dict]:
    """Solve `scene` (with the `--set` overrides) at each level and measure its line contact."""
    loaded = load(scene, overrides)
    out = []
    for lev in levels:
        run = solve(loaded, lev, cold=True)
        lc = hertz.of_model(run.model, run.solution, R)
        out.append(
            {
                "level": lev,
                "unknowns": int(run.model.vi.n + run.model.vi.m),
                "newton": run.solution.iterations,
                "converged": run.solution.converged,
                **lc.record(),
            }
        )
    for prev, row in zip(out[:-1], out[1:], strict=True):
        row["rates"] = {
            k: math.log2(abs(prev["errors"][k]) / abs(row["errors"][k]))
            if row["errors"][k] and prev["errors"][k]
            else None
            for k in ("a", "p0")
        }
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the table; 1 if a level did not converge."""
    ap = argparse.ArgumentParser(
        prog="python benchmarks/hertz_table.py", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--scene", default="hertz", help="a Hertz scene (rigid cylinder at x = 0)")
    ap.add_argument("--levels", default="0..3", help="A..B, the levels solved")
    ap.add_argument("--radius", type=float, default=1.0, help="the cylinder's radius R (m)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--json", default=None, help="write the rows to this JSON file")
    args = ap.parse_args(argv)
    lo, _, hi = args.levels.partition("..")
    try:
        levels = range(int(lo), int(hi or lo) + 1)
    except ValueError:
        ap.error(f"--levels = {args.levels!r}: expected A..B with integers 0 ≤ A ≤ B")
    if not levels or levels.start < 0:
        ap.error(f"--levels = {args.levels!r}: expected A..B with integers 0 ≤ A ≤ B")
    if not args.radius > 0:
        ap.error(f"--radius = {args.radius!r}: expected a radius > 0 (m)")
    outputs = [Output(args.json, "--json", "json")] if args.json else []
    with claim(outputs, load(args.scene).scene.files()) as run:
        table = rows(args.scene, levels, args.radius, args.set)
        print(
            f"{'level':>5} {'unknowns':>9} {'Newton':>6} {'P [N/m]':>10} {'a/a_ref-1':>10} "
            f"{'rate':>5} {'p0/p0_ref-1':>11} {'rate':>5}"
        )
        for r in table:
            rt = r.get("rates", {})

            def fmt(v):
                return f"{v:5.2f}" if v is not None else "    -"

            print(
                f"{r['level']:5d} {r['unknowns']:9d} {r['newton']:6d} {r['P']:10.4g} "
                f"{r['errors']['a']:+10.2e} {fmt(rt.get('a'))} {r['errors']['p0']:+11.2e} "
                f"{fmt(rt.get('p0'))}"
            )
        print(f"E* = {table[0]['E_star']:.6g} Pa (Stroh), R = {args.radius:g} m")
        if args.json:
            run.file("--json").write({"rows": table})
    return 0 if all(r["converged"] for r in table) else 1


if __name__ == "__main__":
    sys.exit(main())
