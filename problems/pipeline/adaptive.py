"""The a posteriori error estimate of a solved model (the plug-in's optional `estimate`): its
files and summary entries (`estimate_output`), its totals (`totals`), and the adaptive loop
that refines where it is large (`adapt`, `mixvi solve --accuracy 1e-3`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from fem.io import write_vtu
from problems.output import plots
from problems.plugins.contract import Indicator
from vi_core import Solution
from vi_core.linalg import resolve_backend


def totals(indicators: dict[str, Indicator]) -> dict[str, float]:
    """{"total": (Σ η_T²)^{1/2} over the bodies, "relative": total / (Σ ‖U_h‖²)^{1/2}}."""
    total = float(np.sqrt(sum(float((i.eta**2).sum()) for i in indicators.values())))
    energy = sum(i.energy for i in indicators.values())
    return {"total": total, "relative": total / np.sqrt(energy) if energy > 0 else float("inf")}


def estimate_output(plugin: Any, model: Any, sol: Solution, outdir: Path) -> dict:
    """With the plug-in's `estimate`: estimate_BODY.vtu (cell field "eta") per body in `outdir`
    and the summary entries {"estimate": {"total", "relative", "bodies": {BODY: total}},
    "files": [...]}; without it, {}."""
    if not hasattr(plugin, "estimate"):
        return {}
    indicators = plugin.estimate(model, sol)
    files = []
    for name, ind in indicators.items():
        write_vtu(outdir / f"estimate_{name}.vtu", ind.mesh, None, {"eta": ind.eta})
        files.append(f"estimate_{name}.vtu")
    bodies = {k: float(np.sqrt((i.eta**2).sum())) for k, i in indicators.items()}
    return {"estimate": {**totals(indicators), "bodies": bodies}, "files": files}


ZoneMarks = Callable[[Any, Solution, dict[str, Any], dict[str, np.ndarray]], dict[str, np.ndarray]]
"""(model, solution, the meshes it was built on, the Dörfler marks, each by body name) →
{body name: its marks} for the bodies whose marks it changes (`adapt`'s `contact_zone`):
(n_cells,) bool, the cells split into 4 (⊇ Dörfler's), or (n_cells,) integers, 2 for a cell
split into 4 (⊇ Dörfler's), 1 for a cell bisected once, 0 for neither (`split_marks`)."""


def split_marks(marks: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """(cells split into 4 (n_cells,) bool, cells bisected once (n_cells,) bool or None) of
    one body's `ZoneMarks` value, for `fem.bisection.refine_marked(mesh, red, bisect=once)`.
    ValueError for integers other than 0, 1, 2."""
    m = np.asarray(marks)
    if m.dtype == bool:
        return m, None
    if not np.isin(m, (0, 1, 2)).all():
        raise ValueError(f"zone marks: bool, or integers 0, 1, 2 per cell; got {np.unique(m)}")
    return m == 2, m == 1


def touching_cells(
    model: Any, sol: Solution, meshes: dict[str, Any], marked: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """`adapt`'s `contact_zone=True`: the slave body's marks and its cells with a vertex at a
    touching contact node."""
    c = model.contact
    touching = c.tr.nodes[c.rows_n][model.contact_state(sol)["touch"]]  # (n_touch,)
    zone = np.isin(meshes[c.slave.name].cells, touching).any(axis=1)  # (n_cells,)
    return {c.slave.name: marked[c.slave.name] | zone}


MAX_UNKNOWNS = 200_000  # the loop's cap on unknowns (`adapt`'s default; `commands.adapt`'s
# where memory allows)


def cycle_linear_solver(asked: str, n: int) -> str:
    """The linear solver of an adaptive cycle whose Newton matrices have n rows: the one
    asked, except "auto": the direct backend (`linalg.resolve_backend`: PARDISO if installed,
    else SuperLU) at every size, where a solve's own "auto" takes amg above
    `linear_solvers.AUTO_AMG_NNZ`. That threshold was placed on uniform levels; on the loop's
    locally refined meshes, on every cycle up to the cap where it takes amg, amg was
    1.06–6.7× slower than SuperLU (their factors fill little, and the nested start from the
    previous mesh can take 10–18 Newton steps, each solved to tolerance on the iterative
    path); past the cap (to 250k unknowns, 4.6M entries) amg was at best 1.5× faster and on
    actuator_tri did not finish where SuperLU took 65 s (docs/benchmarks.md, "The adaptive
    loop's linear solver"). A factorisation over its budget still goes on to amg
    (`ssn.solve_ssn`)."""
    return resolve_backend("auto", n) if asked == "auto" else asked


def adapt(
    plugin: Any,
    scene: Any,
    accuracy: float,
    *,
    theta: float = 0.5,
    max_unknowns: int = MAX_UNKNOWNS,
    max_cycles: int = 30,
    solve_options: dict | None = None,
    on_cycle: Callable[[dict], None] | None = None,
    contact_zone: bool | ZoneMarks = False,
) -> tuple[Any, Solution, list[dict], str]:
    """The adaptive loop: solve → estimate → Dörfler mark (θ, over all bodies' cells at once)
    → newest-vertex bisection (`fem.bisection.refine_marked`) → rebuild the scene on the refined
    meshes (`bodies.given_meshes`) → solve from the plug-in's nested start (`warm_start`: the
    previous solution carried to the new nodes), until the relative estimate is ≤ `accuracy`,
    the next mesh would pass `max_unknowns` (4× the current unknowns, the most one Dörfler step
    can make), `max_cycles`, or a cycle's solve does not converge (its estimate would measure
    the solver's error too and mark for it). Level 0 of the scene is the first mesh
    (quadrilaterals split into triangles: `fem.bisection.prepared`). New boundary nodes of a
    curved part go onto its true curve (the indicators' `curves`, from the geometry), others
    onto the coarse segments. Each cycle is solved with `solve_options`, its linear solver by
    `cycle_linear_solver`.

    `contact_zone`: True, each cycle also marks every cell of the slave body with a vertex at
    a touching contact node (`touching_cells`), so the multiplier's support is refined as a
    whole, red, into similar triangles (the energy estimate alone leaves it graded irregularly
    with green/blue closure cells at the surface, and the nodal multiplier, e.g. the Hertz
    peak pressure, oscillates by ~1 % there: docs/benchmarks.md); or a `ZoneMarks` function
    that extends the Dörfler marks (the benchmarks' other candidate markings:
    `benchmarks/zone_marks.py`), and may ask for cells bisected once (`ZoneMarks`).

    Returns (model, solution, cycles, why it stopped); each cycle is {"cycle", "unknowns",
    "total", "relative" (the estimate: `totals`), "contact_nodes", "converged",
    "linear_solver" (the one that ran), "time_s"} plus the plug-in's exact errors where the
    scene has them ("errors"); `on_cycle(row)` is called after each."""
    from fem.bisection import prepared, refine_marked
    from fem.marking import dorfler_mark
    from problems.plugins.contact.bodies import given_meshes
    from problems.plugins.contract import nested_start, solve_model

    options = dict(solve_options or {})
    asked = options.pop("linear_solver", "auto")
    first = plugin.build(scene, 0)
    level0 = {b.name: b.mesh for b in first.bodies}  # where the scene's geometry was given
    meshes = {n: prepared(m) for n, m in level0.items()}
    cycles: list[dict] = []
    prev = None
    for k in range(max_cycles):
        t0 = time.perf_counter()
        with given_meshes(meshes, level0):
            model = plugin.build(scene, 0)
        start = nested_start(plugin, *prev, model)[0] if prev is not None else {}
        linear_solver = cycle_linear_solver(asked, model.vi.n)
        sol = solve_model(plugin, model, **options, linear_solver=linear_solver, **start)
        indicators = plugin.estimate(model, sol)
        row = {
            "cycle": k,
            "unknowns": int(sum(model.dofs.values())),
            **totals(indicators),
            "contact_nodes": 0 if model.contact is None else int(model.contact.tr.size),
            "converged": bool(sol.converged),
            "linear_solver": sol.info.get("linear_solver", linear_solver),
        }
        errors = plugin.exact_errors(model, sol) if hasattr(plugin, "exact_errors") else None
        if errors is not None:
            row["errors"] = errors
        row["time_s"] = time.perf_counter() - t0
        cycles.append(row)
        if on_cycle is not None:
            on_cycle(row)
        if not sol.converged:  # its estimate measures the solver's error too: marks misled
            return (
                model,
                sol,
                cycles,
                (
                    f"cycle {k}: the solver did not converge (relative residual "
                    f"{sol.residual:.2g} after {sol.iterations} iterations)"
                ),
            )
        if row["relative"] <= accuracy:
            return model, sol, cycles, f"relative estimate {row['relative']:.3g} ≤ {accuracy:g}"
        if 4 * row["unknowns"] > max_unknowns:
            return model, sol, cycles, f"the next mesh could pass {max_unknowns} unknowns"
        names = list(indicators)
        eta = np.concatenate([indicators[n].eta for n in names])  # (Σ n_cells,)
        marked = dict(
            zip(
                names,
                np.split(
                    dorfler_mark(eta, theta),
                    np.cumsum([indicators[n].eta.size for n in names])[:-1],
                ),
                strict=True,
            )
        )
        zone = (
            contact_zone if callable(contact_zone) else (touching_cells if contact_zone else None)
        )
        if zone is not None and model.contact is not None:
            marked.update(zone(model, sol, meshes, marked))
        refined = {}
        for n in names:
            red, once = split_marks(marked[n])
            curves = indicators[n].curves or None
            refined[n] = refine_marked(meshes[n], red, project=curves, bisect=once)[0]
        meshes = refined
        prev = (model, sol)
    return model, sol, cycles, f"{max_cycles} cycles"


def convergence_plot(path: Path, cycles: list[dict], uniform: list[dict], title: str) -> None:
    """Estimate (and the first exact error norm, where there is one) against unknowns, for the
    adaptive cycles and the uniform levels, log-log."""
    plt = plots.pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    err_ax = None
    for rows, style, label in ((cycles, "o-", "adaptive"), (uniform, "s--", "uniform")):
        n = [r["unknowns"] for r in rows]
        ax.loglog(n, [r["total"] for r in rows], style, color="C0", label=f"estimate, {label}")
        if rows and rows[0].get("errors"):  # another unit: its own axis
            key = next(iter(rows[0]["errors"]))
            err_ax = err_ax or ax.twinx()
            err_ax.set_yscale("log")
            err_ax.loglog(n, [r["errors"][key] for r in rows], style, color="C3", mfc="none")
            err_ax.set_ylabel(f"exact error {key} (red)")
    ax.set_xlabel("unknowns")
    ax.set_ylabel("error estimate, energy norm (blue)")
    ax.set_title(f"{title}: adaptive (circles) and uniform (squares)")
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
