"""PNG figures of contact results (matplotlib, Agg backend: no screen needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# the sign convention of every tangential quantity, printed under the contact plots
TAU_NOTE = (
    r"$\tau = (-n_y, n_x)$: the slave's outward normal $n$ turned 90° counterclockwise; "
    r"arc length runs along $\tau$ (the slave body on the left)"
)


def _note(fig) -> None:
    """The τ sign convention at the foot of a figure."""
    fig.text(0.5, 0.01, TAU_NOTE, ha="center", va="bottom", fontsize=7, color="0.3")
    fig.tight_layout(rect=(0, 0.04, 1, 1))


def _shade_slip(ax, s: np.ndarray, slip: np.ndarray) -> None:
    """Shade the slip zones (nodes with |λ·τ| = g) in light red."""
    first = True
    for i in np.flatnonzero(slip):
        a = s[max(i - 1, 0)] * 0.5 + s[i] * 0.5 if i > 0 else s[i]
        b = s[min(i + 1, s.size - 1)] * 0.5 + s[i] * 0.5 if i < s.size - 1 else s[i]
        ax.axvspan(a, b, color="tab:red", alpha=0.12, lw=0, label="slip" if first else None)
        first = False


def contact_plots(state: dict, outdir: Path, title: str = "") -> list[str]:
    """λ·τ with ±g and the tangential jump along Γ3 (one PNG), and u·τ (another)."""
    s, slip = state["s"], state["slip"]
    fig, ax = plt.subplots(figsize=(7, 4))
    _shade_slip(ax, s, slip)
    ax.plot(s, state["lam_t"], "o-", ms=3, color="tab:blue", label=r"$\lambda\cdot\tau$")
    ax.plot(s, state["g"], "k--", lw=1, label=r"$\pm g$")
    ax.plot(s, -state["g"], "k--", lw=1)
    ax.set_xlabel("arc length along $\\Gamma_3$ [m]")
    ax.set_ylabel(r"tangential multiplier $\lambda\cdot\tau$ [Pa]")
    ax2 = ax.twinx()
    ax2.plot(s, state["jump_t"], "s-", ms=2, color="tab:orange", label=r"$[u]\cdot\tau$")
    ax2.set_ylabel(r"tangential jump $[u]\cdot\tau$ [m]", color="tab:orange")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="best", fontsize=8)
    n_slip = int(slip.sum())
    ax.set_title(f"{title}: stick {slip.size - n_slip}, slip {n_slip} nodes")
    _note(fig)
    fig.savefig(outdir / "contact_multiplier.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4))
    _shade_slip(ax, s, slip)
    ax.plot(s, state["ut_slave"], "o-", ms=3, label=r"$u_s\cdot\tau$ (slave)")
    if "ut_master" in state:
        ax.plot(s, state["ut_master"], "s-", ms=3, label=r"$u_m\cdot\tau$ (master)")
    ax.set_xlabel("arc length along $\\Gamma_3$ [m]")
    ax.set_ylabel(r"tangential displacement $u\cdot\tau$ [m]")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title)
    _note(fig)
    fig.savefig(outdir / "contact_displacement.png", dpi=120)
    plt.close(fig)
    return ["contact_multiplier.png", "contact_displacement.png"]


def potential_plot(
    points: np.ndarray, s: np.ndarray, phi: np.ndarray, outdir: Path, where: str
) -> str:
    """φ along a boundary part, against x (and arc length if the part is not straight)."""
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(points[:, 0], phi, "o-", ms=3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel(r"electric potential $\varphi$ [V]")
    ax.set_title(f"potential along {where}")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(outdir / "potential.png", dpi=120)
    plt.close(fig)
    return "potential.png"


def friction_panel(ax, st: dict) -> str:
    """One panel of a friction sweep: λ·τ with ±g and the slip zones, and the tangential jump
    on a twin axis (`st` in the layout of `contact_plots`); returns "stick N, slip M"."""
    _shade_slip(ax, st["s"], st["slip"])
    ax.plot(st["s"], st["lam_t"], "o-", ms=2, label=r"$\lambda\cdot\tau$")
    ax.plot(st["s"], st["g"], "k--", lw=1, label=r"$\pm g$")
    ax.plot(st["s"], -st["g"], "k--", lw=1)
    ax.set_xlabel("arc length along $\\Gamma_3$ [m]")
    ax.set_ylabel(r"$\lambda\cdot\tau$ [Pa]")
    ax2 = ax.twinx()
    ax2.plot(st["s"], st["jump_t"], "s-", ms=2, color="tab:orange", label=r"$[u]\cdot\tau$")
    ax2.set_ylabel(r"$[u]\cdot\tau$ [m]", color="tab:orange")
    ax.legend(loc="best", fontsize=8)
    n_slip = int(st["slip"].sum())
    return f"stick {st['slip'].size - n_slip}, slip {n_slip}"


def sweep_figure(panels: list, draw, path: Path, title: str = "") -> list[str]:
    """One panel per (heading, model, sol) of `panels`, each drawn by draw(ax, model, sol),
    which returns a note appended to the heading; returns the panels' titles."""
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4), squeeze=False)
    titles = []
    for ax, (heading, model, sol) in zip(axes[0], panels, strict=True):
        note = draw(ax, model, sol)
        titles.append(f"{heading}: {note}" if note else heading)
        ax.set_title(titles[-1], fontsize=9)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return titles
