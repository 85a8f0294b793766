"""Which region of an adapted Hertz mesh carries the error of the half-width and of the peak
pressure (docs/benchmarks.md, "Hertz against uniform refinement").

    python benchmarks/hertz_regions.py [--zone NAME] [--cycle C] [--theta θ] [--limit A P0]

Runs the adaptive loop (Dörfler θ on the energy estimate, plus the marking NAME of
`zone_marks.MARKS`, or "energy" for none) to cycle C, then refines one region of that mesh
once (its cells marked, the closure conforming; new nodes on the cylinder) and solves again
from the nested start, for each region: all cells; the far field (centroid farther than ℓ
from every touching node, ℓ the zone's half-length); the near field (nearer than ℓ); the
near field without the touching nodes' fans (the subsurface); the touching nodes' fans
(the surface layer); the fans of the outer half of the zone (|x − x_c| > ℓ/2, the rim) and of
the inner half (the core); the cells within ℓ/4 of the zone's two end nodes (its edge).
Prints per region the unknowns and the signed relative errors a, p0 (× 1e-3) against the
closed form, and a_dis, p0_dis against the finite block's limit A, P0 (default: the
`bench_adaptive.py --zone-levels 5` values, −1.292e-3 and +1.276e-3). What a region's
refinement changes in a is (minus) that region's share of the error in a.
"""

from __future__ import annotations

import argparse

import numpy as np

LIMIT = (-1.292e-3, 1.276e-3)  # a, p0: bench_adaptive.hertz_limit(..., 5)


def regions(model, sol, mesh) -> dict[str, np.ndarray]:
    """{region name: (n_cells,) bool} of the module docstring on the slave mesh."""
    from scipy.spatial import cKDTree

    try:
        from .zone_marks import _cells_at, _touch
    except ImportError:
        from zone_marks import _cells_at, _touch

    c = model.contact
    touch = _touch(model, sol)  # (k,)
    p = mesh.points[c.tr.nodes[touch]]  # (n_touch, 2)
    x = p[:, 0]
    half, xc = 0.5 * (x.max() - x.min()), 0.5 * (x.max() + x.min())
    centroids = mesh.points[mesh.cells].mean(axis=1)  # (n_cells, 2)
    d = cKDTree(p).query(centroids)[0]  # (n_cells,)
    fans = _cells_at(mesh, c.tr.nodes[touch])
    xn = mesh.points[c.tr.nodes, 0]  # (k,)
    ends = p[np.argsort(x)[[0, -1]]]  # (2, 2)
    return {
        "all": np.ones(mesh.n_cells, dtype=bool),
        "far field": d > half,
        "near field": d < half,
        "subsurface": (d < half) & ~fans,
        "surface fans": fans,
        "rim fans": _cells_at(mesh, c.tr.nodes[touch & (np.abs(xn - xc) > 0.5 * half)]),
        "core fans": _cells_at(mesh, c.tr.nodes[touch & (np.abs(xn - xc) <= 0.5 * half)]),
        "edge": cKDTree(ends).query(centroids)[0] < 0.25 * half,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--zone", default="fan_red")
    ap.add_argument("--cycle", type=int, default=8)
    ap.add_argument("--theta", type=float, default=0.5)
    ap.add_argument("--limit", type=float, nargs=2, default=LIMIT, metavar=("A", "P0"))
    args = ap.parse_args()

    from benchmarks import hertz
    from fem.bisection import refine_marked
    from problems import pipeline
    from problems.pipeline.adaptive import adapt
    from problems.plugins.contact.bodies import given_meshes
    from problems.plugins.contract import nested_start, solve_model

    try:
        from .zone_marks import MARKS
    except ImportError:
        from zone_marks import MARKS

    loaded = pipeline.load("hertz")
    plugin, scene = loaded.plugin, loaded.scene
    opts = {"method": "ssn", "tol": 1e-10}
    marks = False if args.zone == "energy" else MARKS[args.zone]
    model, sol = adapt(
        plugin,
        scene,
        1e-9,
        theta=args.theta,
        max_cycles=args.cycle + 1,
        max_unknowns=10**9,
        solve_options=opts,
        contact_zone=marks,
    )[:2]
    name = model.contact.slave.name
    mesh = model.contact.slave.mesh
    curves = plugin.estimate(model, sol)[name].curves or None

    def report(tag, m, s):
        e = hertz.of_model(m, s, 1.0).errors
        da, dp = abs(e["a"] - args.limit[0]), abs(e["p0"] - args.limit[1])
        print(
            f"{tag:>24} {sum(m.dofs.values()):8d} a {e['a'] * 1e3:+.3f} p0 {e['p0'] * 1e3:+.3f}"
            f" a_dis {da:.1e} p0_dis {dp:.1e}",
            flush=True,
        )

    report(f"{args.zone} cycle {args.cycle}", model, sol)
    for tag, marked in regions(model, sol, mesh).items():
        refined = refine_marked(mesh, marked, project=curves)[0]
        with given_meshes({name: refined}):
            m2 = plugin.build(scene, 0)
        s2 = solve_model(plugin, m2, **opts, **nested_start(plugin, model, sol, m2)[0])
        report(f"+ {tag}", m2, s2)


if __name__ == "__main__":
    main()
