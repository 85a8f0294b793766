"""Adaptive against uniform refinement (issue 32, part 4).

    python benchmarks/bench_adaptive.py [--uniform L] [--max-unknowns N] [--json FILE] [SCENE ...]

For each scene (default: hertz and paper_two_body): uniform levels 0..L (default 4) and the
adaptive loop (`problems.pipeline.adaptive.adapt`, Dörfler θ = 0.5, up to N unknowns, default
60,000), each solve from the previous one (nested start), with the CPU time (process_time:
the machine may be shared) accumulated over the levels or cycles, the estimate and, on Hertz,
the relative errors of the contact half-width a and the peak pressure p0 against the closed
form (`problems.plugins.hertz`). Prints the table, then per error measure the first adaptive
cycle that reaches the finest uniform level's value: its unknowns and CPU time against the
uniform level's. Writes all rows as JSON (default bench_adaptive.json) with the peak memory.

The paper example has no closed form: only its estimate is compared; its adaptive meshes keep
the level-0 polygon of the curved interface (new boundary nodes are not projected onto the
arcs), so its geometry is not the uniform levels' (read its row as the estimate only).
"""

from __future__ import annotations

import argparse
import json
import time

HERTZ_R = 1.0  # m, the cylinder radius of the hertz scene


def _measures(name: str, plugin, model, sol) -> dict:
    from problems.pipeline.adaptive import totals
    from problems.plugins import hertz

    row = {"unknowns": int(sum(model.dofs.values())), **totals(plugin.estimate(model, sol))}
    if name == "hertz":
        errors = hertz.of_model(model, sol, HERTZ_R).errors
        row["a_err"], row["p0_err"] = abs(errors["a"]), abs(errors["p0"])
    return row


def run(name: str, levels: int, max_unknowns: int) -> dict:
    from problems import pipeline
    from problems.pipeline import adaptive
    from problems.plugins.contract import nested_start, solve_model

    loaded = pipeline.load(name)
    plugin, scene = loaded.plugin, loaded.scene
    options = {"method": "ssn", "tol": 1e-10}
    uniform, prev, cpu = [], None, 0.0
    for level in range(levels + 1):
        t0 = time.process_time()
        model = plugin.build(scene, level)
        start = nested_start(plugin, *prev, model)[0] if prev else {}
        sol = solve_model(plugin, model, **options, **start)
        cpu += time.process_time() - t0
        uniform.append({"level": level, "cpu_s": cpu, **_measures(name, plugin, model, sol)})
        prev = (model, sol)
    cycles = []
    clock = {"t": time.process_time()}

    def on_cycle(r):
        cycles.append({"cycle": r["cycle"], "cpu_s": time.process_time() - clock["t"]})

    class Measuring:  # the plug-in, measuring each cycle where it is estimated
        def __getattr__(self, attr):
            return getattr(plugin, attr)

        def estimate(self, model, sol):
            spent = time.process_time()
            row = _measures(name, plugin, model, sol)
            clock["t"] += time.process_time() - spent  # not the loop's cost
            Measuring.last = row
            return plugin.estimate(model, sol)

    def record(r):
        on_cycle(r)
        cycles[-1].update(Measuring.last)

    adaptive.adapt(
        Measuring(),
        scene,
        1e-9,
        max_unknowns=max_unknowns,
        solve_options=options,
        on_cycle=record,
    )
    return {"scene": name, "uniform": uniform, "adaptive": cycles, "reach": _reach(uniform, cycles)}


def _reach(uniform: list[dict], cycles: list[dict]) -> dict:
    """Per measure: the finest uniform level's value, and the first adaptive cycle at or below
    it (None: not reached within the size limit)."""
    out = {}
    last = uniform[-1]
    for key in ("total", "a_err", "p0_err"):
        if key not in last:
            continue
        hit = next((c for c in cycles if c[key] <= last[key]), None)
        out[key] = {
            "uniform": {k: last[k] for k in ("level", "unknowns", "cpu_s", key)},
            "adaptive": None
            if hit is None
            else {k: hit[k] for k in ("cycle", "unknowns", "cpu_s", key)},
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=["hertz", "paper_two_body"])
    ap.add_argument("--uniform", type=int, default=4)
    ap.add_argument("--max-unknowns", type=int, default=60_000)
    ap.add_argument("--json", default="bench_adaptive.json")
    args = ap.parse_args()
    from problems.commands.resources import peak_rss

    results = []
    for name in args.scenes:
        res = run(name, args.uniform, args.max_unknowns)
        results.append(res)
        print(f"\n{name}")
        keys = [k for k in ("total", "a_err", "p0_err") if k in res["uniform"][0]]
        print(f"  {'run':>10} {'unknowns':>9} {'cpu s':>8} " + " ".join(f"{k:>10}" for k in keys))
        for r in res["uniform"]:
            vals = " ".join(f"{r[k]:10.3e}" for k in keys)
            print(f"  {'level ' + str(r['level']):>10} {r['unknowns']:9d} {r['cpu_s']:8.2f} {vals}")
        for r in res["adaptive"]:
            vals = " ".join(f"{r[k]:10.3e}" for k in keys)
            print(f"  {'cycle ' + str(r['cycle']):>10} {r['unknowns']:9d} {r['cpu_s']:8.2f} {vals}")
        for key, v in res["reach"].items():
            u, a = v["uniform"], v["adaptive"]
            if a is None:
                print(f"  {key}: uniform level {u['level']} ({u['unknowns']} unknowns) not reached")
            else:
                print(
                    f"  {key}: uniform level {u['level']} {u[key]:.3e} with {u['unknowns']} "
                    f"unknowns, {u['cpu_s']:.2f} s; adaptive cycle {a['cycle']} {a[key]:.3e} with "
                    f"{a['unknowns']} unknowns ({u['unknowns'] / a['unknowns']:.1f}x fewer), "
                    f"{a['cpu_s']:.2f} s"
                )
    peak = peak_rss() / 2**20
    print(f"\npeak memory {peak:.0f} MiB")
    with open(args.json, "w") as fh:
        json.dump({"results": results, "peak_mib": peak}, fh, indent=2)


if __name__ == "__main__":
    main()
