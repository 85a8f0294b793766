"""Coulomb friction on the contact gallery: semismooth Newton against the fixed point on Tresca
problems, over a range of friction coefficients F.

    python benchmarks/bench_coulomb.py [--json FILE] [--seeds N] [--F 0,0.1,...] [--problems A,B]
                                    [--quick]

For each gallery problem (`PROBLEMS`: vi_core.testing.random_contact_vi with 8 contact nodes,
n = 40, 2D and 3D, three operator structures, and the decoupled problem whose pressure does not
depend on friction), each seed and each F it records: Newton converged / steps / time, fixed
point (inner ssn) converged / iterations / inner Newton steps / measured contraction / time, the
independent checker's residual of each answer (vi_core.kkt), and — when both converged — their
relative difference. It prints a table per (problem, F) and the F range where both paths
converge and agree on every seed (difference ≤ AGREE), and writes everything to JSON if asked
(never over an existing file: exit 2). Peak memory is tracemalloc's (Python/numpy objects).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
import tracemalloc
from collections.abc import Callable
from typing import Any

import numpy as np

from vi_core.kkt import Checker
from vi_core.problem import MixedVI
from vi_core.solve import solve
from vi_core.testing import random_contact_vi

TOL = 1e-10
AGREE = 1e-6  # relative difference of λ and of u for "agree"
F_GRID = (0.0, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)


def _gallery(dim: int, structure: str, decoupled: bool = False) -> Callable[[int, float], MixedVI]:
    def build(seed: int, F: float) -> MixedVI:
        return random_contact_vi(
            seed, n=40, k=8, dim=dim, F=F, structure=structure, free=2, rho=1.0,
            decoupled=decoupled,
        )  # fmt: skip

    return build


PROBLEMS: dict[str, Callable[[int, float], MixedVI]] = {
    f"{structure}-{dim}d": _gallery(dim, structure)
    for structure in ("symmetric", "skew-coupled", "general")
    for dim in (2, 3)
}
PROBLEMS["decoupled-2d"] = _gallery(2, "general", decoupled=True)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    den = max(float(np.abs(a).max(initial=0.0)), float(np.abs(b).max(initial=0.0)), 1e-300)
    return float(np.abs(a - b).max(initial=0.0)) / den


def run_case(vi: MixedVI) -> dict[str, Any]:
    """Both paths on one problem: the record described in the module docstring."""
    check = Checker.of(vi)
    newton = solve(vi, "ssn", tol=TOL, linear_solver="splu")
    fixed = solve(vi, "fixed_point", tol=TOL, inner="ssn", linear_solver="splu")
    rec: dict[str, Any] = {
        "newton": {
            "converged": newton.converged,
            "steps": newton.iterations,
            "time_s": newton.time,
            "checker_residual": check(newton.u, newton.lam).relative,
        },
        "fixed_point": {
            "converged": fixed.converged,
            "iterations": fixed.iterations,
            "inner_newton_steps": int(sum(fixed.info["inner_iterations"])),
            "contraction": fixed.info["contraction"],
            "time_s": fixed.time,
            "checker_residual": check(fixed.u, fixed.lam).relative,
        },
    }
    if newton.converged and fixed.converged:
        c = check.contact(newton.u, newton.lam)
        rec["diff_lam"] = _rel(fixed.lam, newton.lam)
        rec["diff_u"] = _rel(fixed.u, newton.u)
        rec["agree"] = max(rec["diff_lam"], rec["diff_u"]) <= AGREE
        rec["nodes"] = {"open": c.open, "stick": c.stick, "slip": c.slip}
    else:
        rec["agree"] = False
    return rec


def run(
    problems: dict[str, Callable[[int, float], MixedVI]], seeds: int, Fs: tuple[float, ...]
) -> dict[str, Any]:
    """All records and the per-problem summary (F range where both paths converge and agree)."""
    records, summary = [], []
    for name, build in problems.items():
        ok_up_to: float | None = None
        broken = False
        for F in Fs:
            for seed in range(seeds):
                rec = {"problem": name, "seed": seed, "F": F, **run_case(build(seed, F))}
                records.append(rec)
                broken = broken or not rec["agree"]
            if not broken:
                ok_up_to = F
        summary.append({"problem": name, "both_converge_and_agree_up_to_F": ok_up_to})
    return {"records": records, "summary": summary}


def _median(values: list) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.median(vals)) if vals else None


def table(result: dict[str, Any]) -> str:
    """One row per (problem, F): counts over seeds and medians over converged runs."""
    head = (
        f"{'problem':<16}{'F':>6}{'both ok':>9}{'N conv':>8}{'FP conv':>8}{'N steps':>9}"
        f"{'FP its':>8}{'FP inner':>9}{'contract':>10}{'max diff':>10}{'t FP/N':>8}"
    )
    lines = [head, "-" * len(head)]
    groups: dict[tuple, list] = {}
    for r in result["records"]:
        groups.setdefault((r["problem"], r["F"]), []).append(r)
    for (name, F), rs in groups.items():
        n_ok = [r for r in rs if r["newton"]["converged"]]
        f_ok = [r for r in rs if r["fixed_point"]["converged"]]
        both = [r for r in rs if r["agree"]]
        diff = max((max(r["diff_lam"], r["diff_u"]) for r in both), default=None)
        ratio = _median([r["fixed_point"]["time_s"] / r["newton"]["time_s"] for r in both])
        contraction = _median([r["fixed_point"]["contraction"] for r in f_ok])

        def fmt(x, spec):  # spec ">W.Pf": "-" right-aligned in W when x is missing
            return format(x, spec) if x is not None else "-".rjust(int(spec[1:].split(".")[0]))

        lines.append(
            f"{name:<16}{F:>6g}{len(both):>5}/{len(rs):<3}{len(n_ok):>8}{len(f_ok):>8}"
            f"{fmt(_median([r['newton']['steps'] for r in n_ok]), '>9.1f')}"
            f"{fmt(_median([r['fixed_point']['iterations'] for r in f_ok]), '>8.1f')}"
            f"{fmt(_median([r['fixed_point']['inner_newton_steps'] for r in f_ok]), '>9.1f')}"
            f"{fmt(contraction, '>10.3f')}{fmt(diff, '>10.1e')}{fmt(ratio, '>8.1f')}"
        )
    lines.append("")
    for s in result["summary"]:
        up_to = s["both_converge_and_agree_up_to_F"]
        lines.append(
            f"{s['problem']}: both paths converge and agree on every seed for F ≤ {up_to}"
            if up_to is not None
            else f"{s['problem']}: not even at F = {result['F'][0]}"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python benchmarks/bench_coulomb.py", description=__doc__)
    parser.add_argument("--json", help="write the records to this new file (never overwritten)")
    parser.add_argument("--seeds", type=int, default=3, help="seeds per problem and F (3)")
    parser.add_argument("--F", help="comma-separated friction coefficients (default: F_GRID)")
    parser.add_argument("--problems", help=f"comma-separated, from: {', '.join(PROBLEMS)}")
    parser.add_argument("--quick", action="store_true", help="one seed, F in {0, 0.5, 5}")
    args = parser.parse_args(argv)
    names = args.problems.split(",") if args.problems else list(PROBLEMS)
    unknown = [x for x in names if x not in PROBLEMS]
    if unknown:
        print(f"--problems {unknown[0]!r}: allowed: {', '.join(PROBLEMS)}", file=sys.stderr)
        return 2
    try:
        Fs = tuple(float(x) for x in args.F.split(",")) if args.F else F_GRID
    except ValueError:
        print(f"--F {args.F!r}: expected comma-separated numbers ≥ 0", file=sys.stderr)
        return 2
    if any(not (F >= 0 and np.isfinite(F)) for F in Fs) or args.seeds < 1:
        print(f"--F {args.F!r} / --seeds {args.seeds}: need F ≥ 0 and seeds ≥ 1", file=sys.stderr)
        return 2
    seeds = args.seeds
    if args.quick:
        Fs, seeds = (0.0, 0.5, 5.0), 1
    out = None
    if args.json:
        try:
            out = open(args.json, "x", encoding="utf-8")  # noqa: SIM115 (kept open until written)
        except FileExistsError:
            print(f"--json {args.json}: the file exists; give a new name", file=sys.stderr)
            return 2
        except OSError as err:
            print(f"--json {args.json}: cannot create it ({err.strerror})", file=sys.stderr)
            return 2
    tracemalloc.start()
    t0 = time.perf_counter()
    result = run({x: PROBLEMS[x] for x in names}, seeds, Fs)
    result["F"] = list(Fs)
    result["seeds"] = seeds
    result["time_s"] = time.perf_counter() - t0
    result["peak_mem_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    result["machine"] = {"python": platform.python_version(), "platform": platform.platform()}
    print(table(result))
    print(f"\ntotal {result['time_s']:.1f} s, peak memory {result['peak_mem_mb']:.1f} MB")
    if out is not None:
        with out:
            json.dump(result, out, indent=1)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
