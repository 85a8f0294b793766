"""Scaling of `mixvi bench` records: fitted exponents and the log-log figure.

For every (scene, linear solver) with at least two sizes that ran and converged, the exponent b
of time ≈ a · N^b (N = unknowns) is the least-squares slope of log time against log N, for the
nonlinear solve, the linear reference solve and the peak resident memory. The figure shows the
three against N on log-log axes, one colour per (scene, linear solver), with the fitted
exponents in the legend and the slopes N^1 and N^1.1 for reference.
"""

from __future__ import annotations

import io

import numpy as np

from problems.output.plots import pyplot

QUANTITIES = {  # JSON key of the fit → record key
    "time_nonlinear": "time_nonlinear_s",
    "time_linear": "time_linear_s",
    "peak_mem": "peak_mem_mb",
}


def slope(x: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope of log y against log x (x, y > 0, at least two distinct x)."""
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    return float(np.polyfit(lx, ly, 1)[0])


def series(records: list[dict]) -> dict[tuple[str, str], list[dict]]:
    """The ssn rows that ran and converged, grouped by (scene, linear solver), sorted by N."""
    out: dict[tuple[str, str], list[dict]] = {}
    for r in records:
        if r.get("error") or not r.get("converged") or r.get("solver") != "ssn":
            continue
        out.setdefault((r["scene"], r.get("linear_solver") or "-"), []).append(r)
    return {k: sorted(v, key=lambda r: r["unknowns"]) for k, v in sorted(out.items())}


def fits(records: list[dict]) -> list[dict]:
    """[{scene, linear_solver, unknowns: [..], exponent: {time_nonlinear, time_linear,
    peak_mem}}] for every series with at least two distinct sizes."""
    rows = []
    for (scene, ls), rs in series(records).items():
        n = np.array([r["unknowns"] for r in rs], float)
        if np.unique(n).size < 2:
            continue
        exps = {q: slope(n, [r[key] for r in rs]) for q, key in QUANTITIES.items()}
        rows.append(
            {
                "scene": scene,
                "linear_solver": ls,
                "unknowns": n.astype(int).tolist(),
                "exponent": exps,
            }
        )
    return rows


def figure_svg(records: list[dict]) -> str:
    """The scaling figure (time and memory against unknowns, log-log) as SVG text."""
    plt = pyplot()
    fitted = {(f["scene"], f["linear_solver"]): f["exponent"] for f in fits(records)}
    fig, (ax_t, ax_m) = plt.subplots(1, 2, figsize=(11, 4.5))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    all_n = []
    for i, ((scene, ls), rs) in enumerate(series(records).items()):
        n = np.array([r["unknowns"] for r in rs], float)
        all_n += n.tolist()
        c = colours[i % len(colours)]
        ex = fitted.get((scene, ls))

        def lab(what, q, ex=ex, scene=scene, ls=ls):
            return f"{scene} {ls} {what}" + (f" (N^{ex[q]:.2f})" if ex else "")

        ax_t.loglog(n, [r["time_nonlinear_s"] for r in rs], "o-", color=c,
                    label=lab("nonlinear", "time_nonlinear"))  # fmt: skip
        ax_t.loglog(n, [r["time_linear_s"] for r in rs], "s--", color=c,
                    label=lab("linear", "time_linear"))  # fmt: skip
        ax_m.loglog(n, [r["peak_mem_mb"] for r in rs], "o-", color=c,
                    label=lab("peak", "peak_mem"))  # fmt: skip
    if all_n:
        lo, hi = min(all_n), max(all_n)
        ref = np.array([lo, hi])
        for ax, key in ((ax_t, "time_nonlinear_s"), (ax_m, "peak_mem_mb")):
            y0 = min(r[key] for rs in series(records).values() for r in rs)
            for b, style in ((1.0, ":"), (1.1, "-.")):
                ax.loglog(ref, y0 * (ref / lo) ** b, style, color="grey", label=f"N^{b:g}")
    ax_t.set(xlabel="unknowns N", ylabel="time [s]", title="solve time (nested ssn, 2 cores)")
    ax_m.set(xlabel="unknowns N", ylabel="peak resident memory [MB]", title="peak memory")
    for ax in (ax_t, ax_m):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    buf = io.StringIO()
    fig.savefig(buf, format="svg")
    plt.close(fig)
    return buf.getvalue()
