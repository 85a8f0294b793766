"""The linear solvers on the adaptive loop's meshes: what `auto` picks against the others.

    python benchmarks/adaptive_solvers.py [SCENE[@ACCURACY] ...] [--accuracy A]
        [--solvers S,...] [--max-unknowns N] [--timeout S] [--out FILE]

SCENE is one of the scenes of benchmarks/user_meshes.py (read from tests/data/user_meshes/),
a shipped scene's name or a scene file (default: the 2D user meshes and the shipped scenes
below). Per scene and linear solver, the adaptive loop (`pipeline.adaptive.adapt`, what
`mixvi solve SCENE --accuracy A --linear-solver S` runs, with its cap of 200,000 unknowns or
--max-unknowns, without writing results) to ACCURACY (default --accuracy, 1e-3: to the cap)
in a child process of its own, killed after --timeout seconds of wall time. Solvers: `auto`
(the loop's default, `adaptive.cycle_linear_solver`), `splu`, `amg` (the iterative path).

Printed per cycle: the unknowns and nnz(A), the solver that ran, Newton steps, GMRES
iterations, the largest fill nnz(L + U) / nnz(K) of the cycle's factorisations, the cycle's
solve CPU time (process_time of the solve alone: all threads of the child) and the peak
resident memory during the cycle (VmHWM, reset before each cycle through
/proc/self/clear_refs). Per scene: auto's solve CPU over the best run's, summed over the
cycles all runs finished. Compare CPU times: the machine may be shared. The JSON (default
adaptive_solvers.json) holds every run; written through `problems.output.files.claim`.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from problems.errors import SceneError
from problems.output.files import Output, claim

try:  # python -m benchmarks.NAME, or imported
    from .runner import in_child
except ImportError:  # python benchmarks/NAME.py
    from runner import in_child

ROOT = Path(__file__).resolve().parents[1]
USER_MESHES = ROOT / "tests" / "data" / "user_meshes"
USER_2D = ("actuator_tri", "actuator_quad", "punch_graded", "cylinder_on_block")
SHIPPED = ("paper_two_body", "hertz", "rigid_foundation", "hertz_piezo", "plate_with_hole")
SOLVERS = ("auto", "splu", "amg")
MAX_UNKNOWNS = 200_000  # `commands.adapt`'s cap where memory allows


def _scene(text: str) -> str:
    """The scene to load for a SCENE argument (without @ACCURACY)."""
    return str(USER_MESHES / f"{text}.toml") if text in USER_2D else text


def _run(scene: str, accuracy: float, solver: str, max_unknowns: int, q) -> None:
    """Child: the adaptive loop of `scene` with `solver`; put its record (or {"error"})."""
    try:
        q.put(_measure(scene, accuracy, solver, max_unknowns))
    except BaseException as err:  # the cause goes into the table
        q.put({"error": f"{type(err).__name__}: {err}".splitlines()[0][:300]})


def _reset_peak() -> None:
    """Reset this process's VmHWM to its resident memory now (Linux; a no-op elsewhere)."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


def _measure(scene: str, accuracy: float, solver: str, max_unknowns: int) -> dict:
    import problems.pipeline as pipeline
    import problems.plugins.contract as contract
    import vi_core.krylov as krylov
    import vi_core.ssn as ssn
    from problems.commands.resources import fix_mmap_threshold, peak_rss
    from problems.pipeline import adaptive

    fix_mmap_threshold()
    fills: list[float] = []  # fill of every factorisation of the cycle running

    class Counted(ssn.Refactorizer):
        def __call__(self, A):
            F = super().__call__(A)
            fills.append(F.fill)
            return F

    ssn.Refactorizer = Counted
    gmres = [0]  # GMRES iterations of the cycle running (every ssn solve of it)
    krylov_solve = krylov.KrylovSolver._solve

    def counted(self, *args):
        x, record = krylov_solve(self, *args)
        gmres[0] += record["iterations"]
        return x, record

    krylov.KrylovSolver._solve = counted
    cycles: list[dict] = []
    solve = contract.solve_model

    def timed(plugin, model, **options):
        fills.clear()
        gmres[0] = 0
        _reset_peak()
        c = time.process_time()
        sol = solve(plugin, model, **options)
        cpu = time.process_time() - c
        info = sol.info
        cycles.append(
            {
                "unknowns": int(sum(model.dofs.values())),
                "nnz_A": int(model.vi.A.nnz),
                "ran": info.get("linear_solver"),
                "newton_steps": int(sol.iterations),
                "krylov_iterations": gmres[0],
                "fallback": info.get("factorisation_fallback", "")
                or "; ".join(f["reason"] for f in info.get("fallback") or []),
                "fill": max(fills, default=None),
                "converged": bool(sol.converged),
                "solve_cpu_s": cpu,
                "peak_mib": peak_rss() / 2**20,
            }
        )
        return sol

    contract.solve_model = timed  # `adapt` imports it at its call
    loaded = pipeline.load(scene)
    c0 = time.process_time()
    try:
        why = adaptive.adapt(
            loaded.plugin,
            loaded.scene,
            accuracy,
            max_unknowns=max_unknowns,
            solve_options={"method": "ssn", "tol": 1e-10, "linear_solver": solver},
            on_cycle=lambda row: cycles[-1].update(relative=row["relative"]),
        )[3]
    except SceneError as err:  # a later cycle's mesh refused: the cycles before it stand
        why = f"SceneError: {err}".splitlines()[0][:300]
        cycles[:] = [c for c in cycles if "relative" in c]
    return {"cycles": cycles, "stopped": why, "cpu_s": time.process_time() - c0}


def _fmt(c: dict) -> str:
    fill = "-" if c["fill"] is None else f"{c['fill']:.1f}"
    note = "" if c["converged"] else "  NOT CONVERGED"
    if c["fallback"]:
        note += f"  fallback: {c['fallback'][:50]}"
    return (
        f"{c['ran']:>6}{c['newton_steps']:>4}{c['krylov_iterations']:>6}{fill:>6}"
        f"{c['solve_cpu_s']:>8.2f}{c['peak_mib']:>6.0f}{note}"
    )


def _table(name: str, runs: dict[str, dict]) -> dict | None:
    """Print one scene's cycles, the solvers side by side; auto's CPU over the best (summed
    over the cycles every run finished), or None."""
    ok = {s: r for s, r in runs.items() if "error" not in r}
    for s, r in runs.items():
        if "error" in r:
            print(f"  {s}: {r['error']}")
    if not ok:
        return None
    first = next(iter(ok.values()))
    print(f"\n{name}: stopped ({next(iter(ok))}): {first['stopped']}")
    cols = "".join(f"{'| ' + s:<36}" for s in ok)
    print(f"{'cycle':>5}{'unknowns':>9}{'nnz(A)':>11}  {cols}")
    sub = f"{'ran':>6}{'N':>4}{'GMRES':>6}{'fill':>6}{'CPU s':>8}{'MiB':>6}  "
    print(f"{'':25}  " + "".join(f"| {sub[:-2]:<34}" for _ in ok))
    n = min(len(r["cycles"]) for r in ok.values())
    for k in range(max(len(r["cycles"]) for r in ok.values())):
        c0 = next(r["cycles"][k] for r in ok.values() if k < len(r["cycles"]))
        cells = "".join(
            f"| {(_fmt(r['cycles'][k]) if k < len(r['cycles']) else '-'):<34}" for r in ok.values()
        )
        print(f"{k:>5}{c0['unknowns']:>9}{c0['nnz_A']:>11}  {cells}")
    total = {s: sum(c["solve_cpu_s"] for c in r["cycles"][:n]) for s, r in ok.items()}
    print(
        "solve CPU over cycles 0…"
        + f"{n - 1}: "
        + ", ".join(f"{s} {t:.1f} s" for s, t in total.items())
    )
    if "auto" not in total:
        return None
    best = min(total, key=total.get)
    ratio = {"ratio": total["auto"] / total[best], "best": best, "cycles": n}
    last = {s: r["cycles"][n - 1]["solve_cpu_s"] for s, r in ok.items()}
    lbest = min(last, key=last.get)
    ratio["last"] = {"ratio": last["auto"] / last[lbest], "best": lbest}
    print(
        f"auto / best: all cycles {ratio['ratio']:.2f} (best {best}), last common cycle "
        f"{ratio['last']['ratio']:.2f} (best {lbest})"
    )
    return ratio


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (prints the tables, writes JSON); exit 2 on bad input."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenes", nargs="*", default=[*USER_2D, *SHIPPED], metavar="SCENE[@ACC]")
    p.add_argument("--accuracy", type=float, default=1e-3, help="relative estimate to reach")
    p.add_argument("--solvers", default=",".join(SOLVERS), help=f"from {', '.join(SOLVERS)}")
    p.add_argument(
        "--max-unknowns",
        type=int,
        default=MAX_UNKNOWNS,
        help=f"the loop's cap (default {MAX_UNKNOWNS:,}, `mixvi solve --accuracy`'s)",
    )
    p.add_argument("--timeout", type=float, default=900.0, help="seconds per run (wall)")
    p.add_argument("--out", default="adaptive_solvers.json")
    args = p.parse_args(argv)
    solvers = [s.strip() for s in args.solvers.split(",") if s.strip()]
    bad = [s for s in solvers if s not in SOLVERS]
    if bad or not solvers:
        p.error(f"--solvers: {', '.join(bad) or 'none'}: expected some of {', '.join(SOLVERS)}")
    cases = []
    for text in args.scenes:
        name, _, acc = text.partition("@")
        try:
            accuracy = float(acc) if acc else args.accuracy
        except ValueError:
            p.error(f"{text}: expected SCENE or SCENE@ACCURACY, e.g. hertz@0.01")
        cases.append((name, _scene(name), accuracy))
    inputs = [("a scene file", s) for _, s, _ in cases if Path(s).is_file()]
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the start")
    records = []
    try:
        with claim([Output(args.out, "--out", "json")], inputs) as out:
            for name, scene, accuracy in cases:
                runs = {}
                for solver in solvers:
                    t = time.monotonic()
                    r = in_child(_run, (scene, accuracy, solver, args.max_unknowns), args.timeout)
                    if r is None:
                        r = {"error": f"killed after {time.monotonic() - t:.0f} s (wall)"}
                    runs[solver] = r
                label = f"{Path(name).stem} to {accuracy:g}"
                ratio = _table(label, runs)
                records.append(
                    {"scene": name, "accuracy": accuracy, "runs": runs, "auto_over_best": ratio}
                )
            meta = {"timeout_s": args.timeout, "max_unknowns": args.max_unknowns}
            out.file("--out").write({**meta, "cases": records})
    except SceneError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"\nload average {os.getloadavg()[0]:.1f} at the end; wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
