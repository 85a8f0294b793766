"""Adaptive against uniform refinement (issue 32, part 4).

    python benchmarks/bench_adaptive.py [--uniform L] [--max-unknowns N] [--zone-levels Z]
        [--contact-zone] [--json FILE] [SCENE ...]
    python benchmarks/bench_adaptive.py --mutations [--uniform L] [--cycles C] [--json FILE]
        [SCENE ...]

For each scene (default: hertz and paper_two_body): uniform levels 0..L (default 4) and the
adaptive loop (`problems.pipeline.adaptive.adapt`, Dörfler θ = 0.5, up to N unknowns, default
60,000), each solve from the previous one (nested start), with the CPU time (process_time:
the machine may be shared) accumulated over the levels or cycles, the estimate and, on Hertz,
the relative errors of the contact half-width a and the peak pressure p0 against the closed
form (`problems.plugins.hertz`: a_err, p0_err). These contain the finite block's own model
error against the half-plane (~1e-3, the floor the uniform levels level off at); with
--zone-levels Z also its discretisation part a_dis, p0_dis: the distance to the finite
block's limit, computed once on a mesh refined Z times more around the contact zone
(`hertz_limit`). Prints the table, then per measure the first adaptive cycle that reaches the
finest uniform level's value: its unknowns and CPU time against the uniform level's. Writes
all rows as JSON (default bench_adaptive.json) with the peak memory.

With --mutations (for the exact-solution scenes, e.g. manufactured curved_manufactured):
per uniform level 0..L (and with --cycles C per adaptive cycle 0..C − 1) the efficiency index
of the contact estimator, its value with each contact term dropped or flipped
(`error_estimate.indicators(..., drop=, flip=)`) and each term's share of η² (1 − η²_dropped /
η²).

The paper example has no closed form: only its estimate is compared (new nodes on its arcs
are projected onto the circle, as the uniform levels' are).
"""

from __future__ import annotations

import argparse
import json
import time

HERTZ_R = 1.0  # m, the cylinder radius of the hertz scene
KEYS = ("total", "a_err", "p0_err", "a_dis", "p0_dis")  # the measures compared


def _measures(name: str, plugin, model, sol, limit: dict | None = None) -> dict:
    from problems.pipeline.adaptive import totals
    from problems.plugins import hertz

    row = {"unknowns": int(sum(model.dofs.values())), **totals(plugin.estimate(model, sol))}
    if name == "hertz":
        errors = hertz.of_model(model, sol, HERTZ_R).errors
        row["a_err"], row["p0_err"] = abs(errors["a"]), abs(errors["p0"])
        if limit is not None:  # the discretisation's part: against the finite block's limit
            row["a_dis"] = abs(errors["a"] - limit["a"])
            row["p0_dis"] = abs(errors["p0"] - limit["p0"])
    return row


def hertz_limit(plugin, scene, zone_levels: int) -> dict:
    """The Hertz errors of the finite block itself (its model error against the half-plane):
    the level-0 mesh split into triangles, refined uniformly 3 times, then `zone_levels` times
    more in the cells meeting the box |x| < b, y > 1 − b around the contact zone (b = 0.12 m,
    × 0.8 per step). {"a", "p0", "unknowns"}."""
    import numpy as np

    from fem.bisection import prepared, refine_marked
    from problems.plugins import hertz
    from problems.plugins.contact.bodies import given_meshes
    from problems.plugins.contract import solve_model

    mesh = prepared(plugin.build(scene, 0).bodies[0].mesh)
    for _ in range(3):
        mesh = refine_marked(mesh, np.ones(mesh.n_cells, dtype=bool))[0]
    box = 0.12
    for _ in range(zone_levels):
        P = mesh.points[mesh.cells]  # (n_cells, 3, 2)
        near = (np.abs(P[..., 0]) < box).any(axis=1) & (P[..., 1] > 1 - box).any(axis=1)
        mesh = refine_marked(mesh, near)[0]
        box *= 0.8
    with given_meshes({"body": mesh}):
        model = plugin.build(scene, 0)
    sol = solve_model(plugin, model, method="ssn", tol=1e-10)
    return {**hertz.of_model(model, sol, HERTZ_R).errors, "unknowns": sum(model.dofs.values())}


def run(
    name: str, levels: int, max_unknowns: int, zone_levels: int = 0, contact_zone: bool = False
) -> dict:
    from problems import pipeline
    from problems.pipeline import adaptive
    from problems.plugins.contract import nested_start, solve_model

    loaded = pipeline.load(name)
    plugin, scene = loaded.plugin, loaded.scene
    options = {"method": "ssn", "tol": 1e-10}
    limit = hertz_limit(plugin, scene, zone_levels) if name == "hertz" and zone_levels else None
    uniform, prev, cpu = [], None, 0.0
    for level in range(levels + 1):
        t0 = time.process_time()
        model = plugin.build(scene, level)
        start = nested_start(plugin, *prev, model)[0] if prev else {}
        sol = solve_model(plugin, model, **options, **start)
        cpu += time.process_time() - t0
        row = _measures(name, plugin, model, sol, limit)
        uniform.append({"level": level, "cpu_s": cpu, **row})
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
            row = _measures(name, plugin, model, sol, limit)
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
        contact_zone=contact_zone,
    )
    return {
        "scene": name,
        "limit": limit,
        "uniform": uniform,
        "adaptive": cycles,
        "reach": _reach(uniform, cycles),
    }


def _reach(uniform: list[dict], cycles: list[dict]) -> dict:
    """Per measure: the finest uniform level's value, and the first adaptive cycle at or below
    it (None: not reached within the size limit)."""
    out = {}
    last = uniform[-1]
    for key in KEYS:
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


def _mutation_row(model, sol) -> dict:
    """{"unknowns", "index", "drop": {term: index}, "flip": {term: index}, "share": {term: its
    share of η²}} of one solution (the efficiency index η / ‖e‖ of the contact estimator)."""
    from problems.plugins.contact import error_estimate as ce
    from problems.plugins.contact import plane as pc

    err = ce.energy_errors(model, sol)

    def index(**mut) -> float:
        return ce.efficiency(ce.indicators(pc.SCENE_MODEL, model, sol, **mut), err)

    row = {"unknowns": int(sum(model.dofs.values())), "index": index()}
    row.update({k: {t: index(**{k: t}) for t in ce.TERMS} for k in ("drop", "flip")})
    row["share"] = {t: 1.0 - (row["drop"][t] / row["index"]) ** 2 for t in ce.TERMS}
    return row


def mutations(name: str, levels: int, cycles: int = 0) -> list[dict]:
    """The rows of `_mutation_row` per uniform level 0..levels of the scene `name` ("level")
    and, with `cycles`, per adaptive cycle 0..cycles − 1 (Dörfler θ = 0.5; "cycle")."""
    from pathlib import Path

    from problems.pipeline import solve_model
    from problems.pipeline.adaptive import adapt
    from problems.plugins.contact import plane as pc
    from problems.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[1] / "problems/scenes" / f"{name}.toml")
    rows = []
    for level in range(levels + 1):
        model = pc.build(scene, level)
        sol = solve_model(pc, model, method="ssn", tol=1e-12)
        rows.append({"level": level, **_mutation_row(model, sol)})

    class Recording:
        """The contact plug-in, with a row recorded at each cycle's estimate."""

        def __getattr__(self, attr):
            return getattr(pc, attr)

        def estimate(self, model, sol):
            rows.append({"cycle": sum("cycle" in r for r in rows), **_mutation_row(model, sol)})
            return pc.estimate(model, sol)

    if cycles:
        options = {"method": "ssn", "tol": 1e-12}
        adapt(Recording(), scene, 1e-12, solve_options=options, max_cycles=cycles)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=["hertz", "paper_two_body"])
    ap.add_argument("--uniform", type=int, default=4)
    ap.add_argument("--max-unknowns", type=int, default=60_000)
    ap.add_argument("--json", default="bench_adaptive.json")
    ap.add_argument(
        "--zone-levels",
        type=int,
        default=0,
        help="Hertz: also the errors against the finite block's limit, computed with this many "
        "refinements of the contact zone (a_dis, p0_dis; 5 is ~130,000 unknowns)",
    )
    ap.add_argument(
        "--contact-zone",
        action="store_true",
        help="the adaptive loop also refines every cell at a touching contact node "
        "(adapt(..., contact_zone=True))",
    )
    ap.add_argument(
        "--mutations",
        action="store_true",
        help="efficiency index with each contact term dropped or flipped (exact-solution scenes)",
    )
    ap.add_argument(
        "--cycles",
        type=int,
        default=0,
        help="with --mutations: also this many adaptive cycles (Dörfler θ = 0.5)",
    )
    args = ap.parse_args()
    from problems.commands.resources import peak_rss

    if args.mutations:
        table = {name: mutations(name, args.uniform, args.cycles) for name in args.scenes}
        for name, rows in table.items():
            for r in rows:
                run = f"level {r['level']}" if "level" in r else f"cycle {r['cycle']}"
                cells = " ".join(
                    f"{t} {r['drop'][t]:.2f}/{r['flip'][t]:.2f} ({100 * r['share'][t]:.2f} %)"
                    for t in r["drop"]
                )
                print(
                    f"{name} {run} ({r['unknowns']} unknowns): index {r['index']:.2f}; "
                    f"dropped/flipped (share of η²) {cells}"
                )
        with open(args.json, "w") as fh:
            json.dump({"mutations": table, "peak_mib": peak_rss() / 2**20}, fh, indent=2)
        return

    results = []
    for name in args.scenes:
        res = run(name, args.uniform, args.max_unknowns, args.zone_levels, args.contact_zone)
        results.append(res)
        print(f"\n{name}")
        keys = [k for k in KEYS if k in res["uniform"][0]]
        if res["limit"]:
            lim = res["limit"]
            print(
                f"  the finite block's own errors (limit, {lim['unknowns']} unknowns): "
                f"a {lim['a']:+.3e}, p0 {lim['p0']:+.3e}"
            )
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
