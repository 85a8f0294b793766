"""Figures of `mixvi study`: errors against h (with reference slopes) and against solve time."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .plots import pyplot, share_scales

LABELS = {
    "u_H1": r"$\|u-u_h\|_{H^1(\Omega)}$ [m]",
    "phi_H1": r"$\|\varphi-\varphi_h\|_{H^1(\Omega)}$ [V]",
    "phi_L2": r"$\|\varphi-\varphi_h\|_{L^2(\Omega)}$ [V m]",
    "lam": r"$(\sum_E h_E\|\lambda-\lambda_h\|^2_{L^2(E)})^{1/2}$ [Pa m]",
    "u_L2": r"$\|u-u_h\|_{L^2(\Omega)}$ [m²]",
    # the scalar plug-ins (antiplane: w in m; obstacle: u in the scene's units)
    "h1": r"$|u-u_h|_{H^1(\Omega)}$ [unit of u]",
    "l2": r"$\|u-u_h\|_{L^2(\Omega)}$ [unit of u · m]",
}
UNITS_NOTE = "H¹ norms mix L² (× m) and gradient parts; lengths in m"


def _series(result: dict, solver: str, tol: float) -> list[dict]:
    """The records of `solver` at `tol` with errors, by level; the reference level's records
    (`"reference": true`: errors against themselves) left out."""
    rows = [
        r
        for r in result["records"]
        if r["solver"] == solver and r["tol"] == tol and not r.get("reference")
    ]
    return sorted((r for r in rows if r.get("err") is not None), key=lambda r: r["level"])


def plot_errors_vs_h(result: dict, path: Path) -> None:
    """(a) each error norm against h at the tightest tolerance, one line per solver, with the
    reference slopes h¹ and h^{1/2} through the coarsest point."""
    tight = min(r["tol"] for r in result["records"])
    solvers = list(dict.fromkeys(r["solver"] for r in result["records"]))
    norms = result["norms"]
    cols = min(len(norms), 2)
    rows_ = -(-len(norms) // cols)
    plt = pyplot()
    fig, axes = plt.subplots(
        rows_, cols, figsize=(5 * cols, 4 * rows_), constrained_layout=True, squeeze=False
    )
    for ax in axes.ravel()[len(norms) :]:
        ax.set_visible(False)
    for ax, k in zip(axes.ravel(), norms, strict=False):
        anchor = None
        for solver in solvers:
            rows = [r for r in _series(result, solver, tight) if r["err"][k] > 0]
            if rows:
                h = np.array([r["h"] for r in rows])  # (p,)
                e = np.array([r["err"][k] for r in rows])  # (p,)
                ax.loglog(h, e, "o-", label=solver)
                anchor = anchor or (h, e[0])
        if anchor is not None:
            h, e0 = anchor
            for p, style in ((1.0, "k--"), (0.5, "k:")):
                ax.loglog(h, e0 * (h / h[0]) ** p, style, label=f"$h^{{{p:g}}}$")
        ax.set_xlabel("mesh size h [m]")
        ax.set_ylabel(LABELS.get(k, k))
        ax.grid(True, which="both", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:  # a norm that is zero everywhere has no line
            ax.legend(fontsize=8)
    fig.suptitle(
        f"{result['scene']}: errors against {result['reference']} (tol {tight:g}); {UNITS_NOTE}",
        fontsize=9,
    )
    share_scales(fig)  # one mesh-size axis for every panel
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_errors_vs_time(result: dict, path: Path) -> None:
    """(b) the speed/accuracy front: the first error norm and the last (for the contact plug-in u
    and λ) against solve time, every level and tolerance, one marker per solver (lines join the
    levels of one tolerance)."""
    solvers = list(dict.fromkeys(r["solver"] for r in result["records"]))
    tols = sorted({r["tol"] for r in result["records"]}, reverse=True)
    shown = list(dict.fromkeys([result["norms"][0], result["norms"][-1]]))
    plt = pyplot()
    fig, axes = plt.subplots(
        1, len(shown), figsize=(5.5 * len(shown), 4.5), constrained_layout=True, squeeze=False
    )
    for ax, k in zip(axes[0], shown, strict=True):
        for i, solver in enumerate(solvers):
            color = f"C{i}"
            for j, tol in enumerate(tols):
                rows = [r for r in _series(result, solver, tol) if r["err"][k] > 0]
                t = [max(r["time_s"], 1e-4) for r in rows]
                ax.loglog(
                    t,
                    [r["err"][k] for r in rows],
                    marker="osd^v"[j % 5],
                    color=color,
                    alpha=0.4 + 0.6 * (j + 1) / len(tols),
                    label=f"{solver} tol {tol:g}",
                )
        ax.set_xlabel("solve time [s] (wall clock)")
        ax.set_ylabel(LABELS.get(k, k))
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{result['scene']}: speed/accuracy (errors against {result['reference']})")
    fig.savefig(path, dpi=120)
    plt.close(fig)
