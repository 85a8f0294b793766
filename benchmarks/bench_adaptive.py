"""Adaptive against uniform refinement.

    python benchmarks/bench_adaptive.py [--uniform L] [--max-unknowns N] [--zone-levels Z]
        [--contact-zone | --zone NAME ...] [--box U,Z,W,D,S ...] [--limit-box W,D]
        [--set KEY=VALUE ...] [--radius R] [--json FILE] [SCENE ...]
    python benchmarks/bench_adaptive.py --mutations [--uniform L] [--cycles C] [--json FILE]
        [SCENE ...]

For each scene (default: hertz and paper_two_body): uniform levels 0..L (default 4) and the
adaptive loop (`problems.pipeline.adaptive.adapt`, Dörfler θ = 0.5, up to N unknowns, default
60,000), each solve from the previous one (nested start), with the CPU time (process_time:
the machine may be shared) accumulated over the levels or cycles, the estimate and, on Hertz,
the relative errors of the contact half-width a and the peak pressure p0 against the closed
form (`benchmarks.hertz`: a_err, p0_err). These contain the finite block's own model
error against the half-plane (~1e-3, the floor the uniform levels level off at); with
--zone-levels Z also its discretisation part a_dis, p0_dis: the distance to the finite
block's limit, computed once on a mesh refined Z times more around the contact zone
(`hertz_limit`, its box |x| < W, depth D: --limit-box W,D, default 0.075,0.12 for the
shipped load's a = 0.058 m), and the signed errors a, p0 in the JSON. --set KEY=VALUE ...
overrides the scenes' fields as `mixvi solve --set` does (e.g. another load on Hertz:
--set 'body.displacement=[{boundary = "bottom", value = [0.0, 3.0e-3]}]'); --radius R sets
the Hertz cylinder's radius (the gap x²/(2R) and the closed form's R, default HERTZ_R). On
Hertz each row also has the measured load P (N/m) and the closed form's a_ref (m) at it.
With --zone NAME ... one adaptive run per NAME: "energy" (the Dörfler marks alone, the
default) or a candidate contact-zone marking of `benchmarks/zone_marks.py` (--contact-zone
is --zone touching), or NAME@KEY=VALUE,... for one of its functions with those keywords
(`zone_marking`). On Hertz also two diagnostics of the nodal pressure at the centre
(`_centre`: "osc", the centre node against its neighbours' mean, and "h0", the segment
length there) and, with --box, a priori meshes refined around the zone (`box_mesh`), one
solve each. Prints the table, then per run and measure the first adaptive cycle that reaches
the finest uniform level's value: its unknowns and CPU time against the uniform level's, and
on Hertz the first cycle that reaches both a_dis and p0_dis. Writes all rows as JSON
(default bench_adaptive.json) with the peak memory.

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
import sys
import time
from collections.abc import Callable
from pathlib import Path

if not __package__:  # run as python benchmarks/bench_adaptive.py: `benchmarks` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

HERTZ_R = 1.0  # m, the cylinder radius of the hertz scene
HERTZ_ZONE = 0.075  # m, the limit's box half-width: the contact half-width a = 0.058 m and 30 %
HERTZ_DEPTH = 0.12  # m, the limit's box depth at its first step (2.07 a)
KEYS = ("total", "a_err", "p0_err", "a_dis", "p0_dis")  # the measures compared
CENTRE = ("osc", "h0")  # Hertz diagnostics printed beside them (`_centre`)


def _measures(
    name: str, plugin, model, sol, limit: dict | None = None, radius: float = HERTZ_R
) -> dict:
    from benchmarks import hertz
    from problems.pipeline.adaptive import totals

    row = {"unknowns": int(sum(model.dofs.values())), **totals(plugin.estimate(model, sol))}
    if name == "hertz":
        contact = hertz.of_model(model, sol, radius)
        errors = contact.errors
        row["P"], row["a_ref"] = contact.P, contact.a_ref
        row["a"], row["p0"] = errors["a"], errors["p0"]  # signed
        row.update(_centre(model, sol, contact.p0_ref))
        row["a_err"], row["p0_err"] = abs(errors["a"]), abs(errors["p0"])
        if limit is not None:  # the discretisation's part: against the finite block's limit
            row["a_dis"] = abs(errors["a"] - limit["a"])
            row["p0_dis"] = abs(errors["p0"] - limit["p0"])
    return row


def _centre(model, sol, p0_ref: float) -> dict:
    """The nodal pressures at the centre (diagnostics, not measures): "osc", the centre node's
    λ_n against the mean of its two neighbours', relative to p0_ref (the odd-even mode of the
    nodal multiplier: a smooth p gives +h0²/(2a²), ~2e-5 at h0 = 0.35 mm), and "h0", the mean
    length of the two contact segments at x = 0 (m)."""
    import numpy as np

    c = model.contact
    x = c.slave.mesh.points[c.tr.nodes[c.rows_n], 0]  # (N_n,)
    lam = c.normal(sol.lam)  # (N_n,)
    order = np.argsort(x)
    k = int(np.argmin(np.abs(x[order])))
    left, mid, right = order[k - 1], order[k], order[k + 1]
    return {
        "osc": float((lam[mid] - 0.5 * (lam[left] + lam[right])) / p0_ref),
        "h0": float(0.5 * (x[right] - x[left])),
    }


def box_mesh(plugin, scene, uniform: int, steps: int, width: float, depth: float, shrink: float):
    """The level-0 mesh split into triangles, refined `uniform` times uniformly, then `steps`
    times more in the cells meeting the box |x| < width, y > 1 − d (d = depth, × shrink per
    step): an a priori mesh around the Hertz zone (x = 0 its centre, y = 1 the surface)."""
    import numpy as np

    from fem.bisection import prepared, refine_marked

    mesh = prepared(plugin.build(scene, 0).bodies[0].mesh)
    for _ in range(uniform):
        mesh = refine_marked(mesh, np.ones(mesh.n_cells, dtype=bool))[0]
    for _ in range(steps):
        P = mesh.points[mesh.cells]  # (n_cells, 3, 2)
        near = (np.abs(P[..., 0]) < width).any(axis=1) & (P[..., 1] > 1 - depth).any(axis=1)
        mesh = refine_marked(mesh, near)[0]
        depth *= shrink
    return mesh


def _solve_on(plugin, scene, mesh):
    from problems.plugins.contact.bodies import given_meshes
    from problems.plugins.contract import solve_model

    with given_meshes({"body": mesh}):
        model = plugin.build(scene, 0)
    return model, solve_model(plugin, model, method="ssn", tol=1e-10)


def hertz_limit(
    plugin,
    scene,
    zone_levels: int,
    width: float = HERTZ_ZONE,
    depth: float = HERTZ_DEPTH,
    radius: float = HERTZ_R,
) -> dict:
    """The Hertz errors of the finite block itself (its model error against the half-plane):
    `box_mesh` with 3 uniform steps and `zone_levels` box steps, |x| < width, d = depth × 0.8
    per step (defaults for the shipped load; scale both with a for another; the box's width
    stays: a box shrinking with d leaves the zone's edge x = a one level coarser from step 4
    on, and its errors were off by 1.8e-4 in a and 1.6e-4 in p0: the history of
    docs/benchmarks.md), against the closed form for a cylinder of this `radius`.
    {"a", "p0", "unknowns"}."""
    from benchmarks import hertz

    mesh = box_mesh(plugin, scene, 3, zone_levels, width, depth, 0.8)
    model, sol = _solve_on(plugin, scene, mesh)
    errors = hertz.of_model(model, sol, radius).errors
    return {**errors, "unknowns": sum(model.dofs.values())}


def run(
    name: str,
    levels: int,
    max_unknowns: int,
    zone_levels: int = 0,
    zones: tuple[str, ...] = ("energy",),
    theta: float = 0.5,
    boxes: tuple[tuple[int, int, float, float, float], ...] = (),
    overrides: tuple[str, ...] = (),
    limit_box: tuple[float, float] = (HERTZ_ZONE, HERTZ_DEPTH),
    radius: float | None = None,
) -> dict:
    """Uniform levels 0..levels, then one adaptive run per entry of `zones` ("energy": the
    Dörfler marks alone; else a name of `zone_marks.MARKS` added to them), Dörfler θ = `theta`;
    on Hertz one solve per entry of `boxes` ((uniform, steps, width, depth, shrink) of
    `box_mesh`: a priori meshes, CPU time of the solve alone). `overrides`: the scene's `--set`
    overrides (`pipeline.load`); `limit_box`: (width, depth) of `hertz_limit`'s box; `radius`:
    on Hertz the cylinder's (its gap x²/(2R) set on the scene; None: the scene's HERTZ_R)."""
    from problems import pipeline
    from problems.plugins.contract import nested_start, solve_model

    if name == "hertz" and radius is not None:
        overrides = (*overrides, f'contact.gap="x**2 / (2 * {radius!r})"')
    radius = HERTZ_R if radius is None else radius
    loaded = pipeline.load(name, overrides)
    plugin, scene = loaded.plugin, loaded.scene
    options = {"method": "ssn", "tol": 1e-10}
    limit = (
        hertz_limit(plugin, scene, zone_levels, *limit_box, radius)
        if name == "hertz" and zone_levels
        else None
    )
    uniform, prev, cpu = [], None, 0.0
    for level in range(levels + 1):
        t0 = time.process_time()
        model = plugin.build(scene, level)
        start = nested_start(plugin, *prev, model)[0] if prev else {}
        sol = solve_model(plugin, model, **options, **start)
        cpu += time.process_time() - t0
        row = _measures(name, plugin, model, sol, limit, radius)
        uniform.append({"level": level, "cpu_s": cpu, **row})
        prev = (model, sol)
    box_rows = []
    for spec in boxes if name == "hertz" else ():
        mesh = box_mesh(plugin, scene, *spec)
        t0 = time.process_time()
        model, sol = _solve_on(plugin, scene, mesh)
        cpu_s = time.process_time() - t0
        box_rows.append(
            {
                "box": list(spec),
                "cpu_s": cpu_s,
                **_measures(name, plugin, model, sol, limit, radius),
            }
        )
    runs = {
        zone: _adaptive(name, plugin, scene, max_unknowns, options, limit, zone, theta, radius)
        for zone in zones
    }
    return {
        "scene": name,
        "limit": limit,
        "uniform": uniform,
        "adaptive": runs,
        "boxes": box_rows,
        "reach": {zone: _reach(uniform, cycles) for zone, cycles in runs.items()},
        "overrides": list(overrides),
        "limit_box": list(limit_box),
    }


def zone_marking(spec: str) -> Callable[..., dict]:
    """The marking of `--zone SPEC`: a name of `zone_marks.MARKS`, or NAME@KEY=VALUE,... with
    NAME a function of `zone_marks.MARKS` taking those keyword arguments (numbers), e.g.
    near_box@factor=2.4,width=1.1: that function with them. ValueError for an unknown name, a
    NAME that takes no keywords, or a bad KEY=VALUE."""
    import functools
    import inspect

    from benchmarks.zone_marks import MARKS

    name, _, args = spec.partition("@")
    if name not in MARKS:
        raise ValueError(f"unknown marking {name!r}; known: energy, {', '.join(MARKS)}")
    if not args:
        return MARKS[name]
    try:
        kw = {k: float(v) for k, v in (a.split("=") for a in args.split(","))}
    except ValueError:
        raise ValueError(f"{spec!r}: NAME@KEY=VALUE,... with numbers as values") from None
    params = list(inspect.signature(MARKS[name]).parameters.values())[4:]  # after the 4 given
    bad = sorted(set(kw) - {p.name for p in params if p.kind is p.POSITIONAL_OR_KEYWORD})
    if bad:
        raise ValueError(f"{spec!r}: {name} takes no keyword(s) {bad}")
    return functools.partial(MARKS[name], **kw)


def _adaptive(
    name, plugin, scene, max_unknowns, options, limit, zone, theta=0.5, radius=HERTZ_R
) -> list[dict]:
    """The adaptive loop's cycles with the measures and the CPU time summed over cycles."""
    from problems.pipeline import adaptive

    cycles = []
    clock = {"t": time.process_time()}

    def on_cycle(r):
        cycles.append({"cycle": r["cycle"], "cpu_s": time.process_time() - clock["t"]})

    class Measuring:  # the plug-in, measuring each cycle where it is estimated
        def __getattr__(self, attr):
            return getattr(plugin, attr)

        def estimate(self, model, sol):
            spent = time.process_time()
            row = _measures(name, plugin, model, sol, limit, radius)
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
        theta=theta,
        max_unknowns=max_unknowns,
        solve_options=options,
        on_cycle=record,
        contact_zone=False if zone == "energy" else zone_marking(zone),
    )
    return cycles


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
    if "a_dis" in last:  # both Hertz measures in one cycle
        hit = next(
            (c for c in cycles if c["a_dis"] <= last["a_dis"] and c["p0_dis"] <= last["p0_dis"]),
            None,
        )
        out["both"] = None if hit is None else {k: hit[k] for k in ("cycle", "unknowns", "cpu_s")}
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
        "(adapt(..., contact_zone=True)); the same as --zone touching",
    )
    ap.add_argument(
        "--zone",
        nargs="+",
        default=None,
        metavar="NAME",
        help="one adaptive run per NAME: energy (the Dörfler marks alone) or a candidate "
        "contact-zone marking of benchmarks/zone_marks.py (touching, edge, edge_peak, jump, "
        "rough, graded, NAME_graded, fan_red, peak_red, core_red, contact_w10, near_zone, "
        "zone_weighted, ...; the list: zone_marks.MARKS), or NAME@KEY=VALUE,... for a "
        "function's keywords, e.g. near_box@factor=2.4,width=1.1",
    )
    ap.add_argument(
        "--theta",
        type=float,
        default=0.5,
        help="the adaptive loops' Dörfler bulk fraction (default 0.5, what mixvi solve uses)",
    )
    ap.add_argument(
        "--box",
        nargs="+",
        default=[],
        metavar="U,Z,W,D,S",
        help="Hertz: also a priori meshes refined U times uniformly, then Z times in the box "
        "|x| < W, y > 1 - D (D × S per step) (bench_adaptive.box_mesh), one solve each",
    )
    ap.add_argument(
        "--limit-box",
        default=f"{HERTZ_ZONE},{HERTZ_DEPTH}",
        metavar="W,D",
        help="Hertz: the limit's box |x| < W, first depth D (m; default for the shipped load's "
        "a = 0.058 m: scale both with a for another load)",
    )
    ap.add_argument(
        "--radius",
        type=float,
        default=None,
        help="Hertz: the cylinder's radius R (m; the gap x²/(2R) and the closed form's R; "
        f"default the scene's {HERTZ_R})",
    )
    ap.add_argument(
        "--set",
        dest="overrides",
        nargs="+",
        default=[],
        metavar="KEY=VALUE",
        help="scene overrides as mixvi solve --set, applied to every SCENE, e.g. "
        "'body.displacement=[{boundary = \"bottom\", value = [0.0, 3.0e-3]}]'",
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
                label = f"level {r['level']}" if "level" in r else f"cycle {r['cycle']}"
                cells = " ".join(
                    f"{t} {r['drop'][t]:.2f}/{r['flip'][t]:.2f} ({100 * r['share'][t]:.2f} %)"
                    for t in r["drop"]
                )
                print(
                    f"{name} {label} ({r['unknowns']} unknowns): index {r['index']:.2f}; "
                    f"dropped/flipped (share of η²) {cells}"
                )
        with open(args.json, "w") as fh:
            json.dump({"mutations": table, "peak_mib": peak_rss() / 2**20}, fh, indent=2)
        return

    zones = args.zone or ["touching" if args.contact_zone else "energy"]
    if args.contact_zone and args.zone:
        ap.error("--contact-zone is --zone touching: give one of them")
    for z in zones:
        if z != "energy":
            try:
                zone_marking(z)
            except ValueError as err:
                ap.error(f"--zone: {err}")
    try:
        boxes = tuple(
            (int(u), int(z), float(w), float(d), float(sh))
            for u, z, w, d, sh in (b.split(",") for b in args.box)
        )
    except ValueError:
        ap.error(f"--box: U,Z,W,D,S each (two integers, three numbers), got {args.box}")
    try:
        width, depth = (float(v) for v in args.limit_box.split(","))
    except ValueError:
        ap.error(f"--limit-box: W,D (two numbers), got {args.limit_box}")
    results = []
    for name in args.scenes:
        res = run(
            name,
            args.uniform,
            args.max_unknowns,
            args.zone_levels,
            tuple(zones),
            args.theta,
            boxes,
            tuple(args.overrides),
            (width, depth),
            args.radius,
        )
        results.append(res)
        print(f"\n{name}")
        keys = [k for k in (*KEYS, *CENTRE) if k in res["uniform"][0]]
        if res["limit"]:
            lim = res["limit"]
            print(
                f"  the finite block's own errors (limit, {lim['unknowns']} unknowns): "
                f"a {lim['a']:+.3e}, p0 {lim['p0']:+.3e}; box {res['limit_box']}"
            )
        if res["overrides"]:
            print(f"  --set {' '.join(res['overrides'])}")
        if "P" in res["uniform"][-1]:
            last = res["uniform"][-1]
            print(f"  load P {last['P']:.4e} N/m, a_ref {last['a_ref']:.4e} m (finest level)")
        print(f"  {'run':>16} {'unknowns':>9} {'cpu s':>8} " + " ".join(f"{k:>10}" for k in keys))
        for r in res["uniform"]:
            vals = " ".join(f"{r[k]:10.3e}" for k in keys)
            print(f"  {'level ' + str(r['level']):>16} {r['unknowns']:9d} {r['cpu_s']:8.2f} {vals}")
        for r in res["boxes"]:
            vals = " ".join(f"{r[k]:10.3e}" for k in keys)
            label = "box " + "/".join(f"{v:g}" for v in r["box"])
            print(f"  {label:>16} {r['unknowns']:9d} {r['cpu_s']:8.2f} {vals}")
        for zone, cycles in res["adaptive"].items():
            for r in cycles:
                vals = " ".join(f"{r[k]:10.3e}" for k in keys)
                run_name = f"{zone} {r['cycle']}"
                print(f"  {run_name:>16} {r['unknowns']:9d} {r['cpu_s']:8.2f} {vals}")
        for zone, reach in res["reach"].items():
            for key, v in reach.items():
                if key == "both":
                    got = (
                        "not reached"
                        if v is None
                        else (f"cycle {v['cycle']}, {v['unknowns']} unknowns, {v['cpu_s']:.2f} s")
                    )
                    print(f"  {zone}: a_dis and p0_dis of the finest level both: {got}")
                    continue
                u, a = v["uniform"], v["adaptive"]
                if a is None:
                    print(f"  {zone} {key}: uniform level {u['level']} not reached")
                else:
                    print(
                        f"  {zone} {key}: uniform level {u['level']} {u[key]:.3e} with "
                        f"{u['unknowns']} unknowns, {u['cpu_s']:.2f} s; cycle {a['cycle']} "
                        f"{a[key]:.3e} with {a['unknowns']} unknowns "
                        f"({u['unknowns'] / a['unknowns']:.1f}x fewer), {a['cpu_s']:.2f} s"
                    )
    peak = peak_rss() / 2**20
    print(f"\npeak memory {peak:.0f} MiB")
    with open(args.json, "w") as fh:
        json.dump({"results": results, "peak_mib": peak}, fh, indent=2)


if __name__ == "__main__":
    main()
