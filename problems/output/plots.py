"""PNG figures of contact results (matplotlib, Agg backend: no screen needed).

Every axis says what it shows in words with its unit; panels of one figure that show the same
quantity (the same axis label, or mappables with the same label) share one scale, so sizes
compare at a glance (`share_scales`); a figure with tangential quantities states the sign
convention of the tangent at its foot. A plug-in whose tangent is not τ (antiplane: e_z) gives
its own labels and note in the contact state ("tangent_note", "lam_label", "jump_label",
"ut_label")."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

# the sign convention of every tangential quantity, printed under the contact plots
TAU_NOTE = (
    r"sign convention: $\tau = (-n_y, n_x)$, the slave's outward normal $n$ turned 90° "
    r"counterclockwise; arc length runs along $\tau$ (the slave body on the left); "
    r"$\lambda\cdot\tau > 0$: the slave is pulled along $-\tau$"
)
NOTE_GID = "mixvi-tangent-note"  # the gid of the note's text (one per figure)
LABELS = {
    "lam_label": r"tangential multiplier $\lambda\cdot\tau$ [Pa]",
    "jump_label": r"tangential jump $[u]\cdot\tau$ [m]",
    "ut_label": r"tangential displacement $u\cdot\tau$ [m]",
    "s_label": r"arc length along the contact boundary $\Gamma_3$ [m]",
}


# the friction bound's legend entry per friction law (a contact state's "friction")
BOUNDS = {
    "tresca": r"friction bound $\pm g$",
    "coulomb": r"friction bound $\pm F\lambda_n$",
}


def pyplot():
    """matplotlib.pyplot on the Agg backend, imported on first use: commands that draw
    nothing (validate, a solve without figures) do not pay its ~0.6 s import."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _label(state: dict, key: str) -> str:
    return state.get(key, LABELS[key])


def bound_label(state: dict) -> str:
    """The legend entry of the friction bound: ±g (Tresca, the default), ±F·λ_n (Coulomb)."""
    return BOUNDS[state.get("friction", "tresca")]


def state_counts(state: dict) -> str:
    """ "stick N, slip M" and, where there are any, the open and ambiguous nodes, counted from
    the per-node labels "state" (without them: every node not slipping counts as stick)."""
    labels = state.get("state")
    if labels is None:
        n_slip = int(state["slip"].sum())
        return f"stick {state['slip'].size - n_slip}, slip {n_slip}"
    labels = np.asarray(labels)
    parts = [f"{s} {int((labels == s).sum())}" for s in ("stick", "slip")]
    parts += [f"{s} {n}" for s in ("open", "ambiguous") if (n := int((labels == s).sum()))]
    return ", ".join(parts)


def direction_label(v, unit: str = "m") -> str:
    """An axis label for the coordinate along the unit vector `v` (3,): "x [m]" for e_x (to
    two decimals: [1, 0, 0.0033] is x), else its combination of x, y, z, e.g.
    "0.71 x + 0.71 z [m]"."""
    terms = []
    for c, name in zip(np.round(np.asarray(v, dtype=float), 2), "xyz", strict=True):
        if c == 0:
            continue
        mag = "" if abs(c) == 1 else f"{abs(c):.2g} "
        sign = "−" if c < 0 else "+"
        terms.append((sign, mag + name))
    if not terms:
        return f"[{unit}]"
    text = ("−" if terms[0][0] == "−" else "") + terms[0][1]
    text += "".join(f" {sign} {t}" for sign, t in terms[1:])
    return f"{text} [{unit}]"


NOTE_POINTS = 7  # font size of the note
NOTE_CHAR = 0.5 * NOTE_POINTS  # mean width of one of its characters [pt] (DejaVu Sans)


def add_note(fig, text: str) -> None:
    """The sign convention `text` at the foot of `fig` (once, however many panels ask), broken
    into lines that fit the figure's width."""
    if not any(t.get_gid() == NOTE_GID for t in fig.texts):
        width = int(0.95 * fig.get_figwidth() * 72 / NOTE_CHAR)  # characters a line
        lines = textwrap.fill(text, width)
        fig.text(0.5, 0.01, lines, ha="center", va="bottom", fontsize=NOTE_POINTS, color="0.3",
                 gid=NOTE_GID)  # fmt: skip


def _finish(fig) -> None:
    """Shared scales, and room at the foot for the note's lines if there is one."""
    share_scales(fig)
    note = [t for t in fig.texts if t.get_gid() == NOTE_GID]
    rows = len(note[0].get_text().splitlines()) if note else 0
    foot = (0.01 + 1.3 * NOTE_POINTS * rows / 72 / fig.get_figheight()) if rows else 0
    fig.tight_layout(rect=(0, foot, 1, 1))


def _data_range(ax, which: str, log: bool = False) -> tuple[float, float] | None:
    """The range of the finite (on a log axis: positive) data of `ax`'s lines along `which`
    (None: no data)."""
    vals = [
        np.asarray(line.get_ydata() if which == "y" else line.get_xdata(), dtype=float)
        for line in ax.get_lines()
    ]
    vals = [v[np.isfinite(v) & ((v > 0) if log else True)] for v in vals if v.size]
    vals = [v for v in vals if v.size]
    if not vals:
        return None
    return min(float(v.min()) for v in vals), max(float(v.max()) for v in vals)


def share_scales(fig) -> None:
    """One scale per quantity across the panels of `fig`: axes with the same y label get one
    y range, the union of their data with a 5 % margin (twin axes included), those with the
    same x label one x range, and colour-mapped artists with the same label one colour
    range."""
    for which in ("y", "x"):
        groups: dict[str, list] = {}
        for ax in fig.axes:
            label = ax.get_ylabel() if which == "y" else ax.get_xlabel()
            if label:
                groups.setdefault(label, []).append(ax)
        for axes in groups.values():
            log = {(ax.get_yscale() if which == "y" else ax.get_xscale()) == "log" for ax in axes}
            ranges = [r for r in (_data_range(ax, which, log == {True}) for ax in axes) if r]
            if len(axes) < 2 or not ranges or len(log) > 1:
                continue
            lo, hi = min(r[0] for r in ranges), max(r[1] for r in ranges)
            if log == {True}:  # a factor of margin on a log axis
                lo, hi = lo / 1.2, hi * 1.2
            else:
                pad = 0.05 * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.05
                lo, hi = lo - pad, hi + pad
            for ax in axes:
                (ax.set_ylim if which == "y" else ax.set_xlim)(lo, hi)
    mappables: dict[str, list] = {}
    for ax in fig.axes:
        for m in [*ax.images, *ax.collections]:
            label = m.get_label()
            if m.get_array() is not None and label and not label.startswith("_"):
                mappables.setdefault(label, []).append(m)
    for ms in mappables.values():
        lo = min(float(np.nanmin(m.get_array())) for m in ms)
        hi = max(float(np.nanmax(m.get_array())) for m in ms)
        for m in ms:
            m.set_clim(lo, hi)


def _shade_slip(ax, s: np.ndarray, slip: np.ndarray) -> None:
    """Shade the slip zones (nodes with |λ·τ| = g) in light red."""
    first = True
    for i in np.flatnonzero(slip):
        a = s[max(i - 1, 0)] * 0.5 + s[i] * 0.5 if i > 0 else s[i]
        b = s[min(i + 1, s.size - 1)] * 0.5 + s[i] * 0.5 if i < s.size - 1 else s[i]
        ax.axvspan(a, b, color="tab:red", alpha=0.12, lw=0, label="slip" if first else None)
        first = False


def contact_plots(state: dict, outdir: Path, title: str = "") -> list[str]:
    """λ·τ with the friction bound (±g; Coulomb, `state["friction"]`: ±F·λ_n) and the
    tangential jump along Γ3 (one PNG), and u·τ (another); the title counts the nodes by their
    labels (`state_counts`)."""
    plt = pyplot()
    s, slip = state["s"], state["slip"]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.set_title(f"{title}: {friction_panel(ax, state, ms=3, fontsize=8)} nodes")
    _finish(fig)
    fig.savefig(outdir / "contact_multiplier.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4))
    _shade_slip(ax, s, slip)
    ax.plot(s, state["ut_slave"], "o-", ms=3, label="slave")
    if "ut_master" in state:
        ax.plot(s, state["ut_master"], "s-", ms=3, label="master (projected)")
    ax.set_xlabel(_label(state, "s_label"))
    ax.set_ylabel(_label(state, "ut_label"))
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title)
    add_note(fig, state.get("tangent_note", TAU_NOTE))
    _finish(fig)
    fig.savefig(outdir / "contact_displacement.png", dpi=120)
    plt.close(fig)
    return ["contact_multiplier.png", "contact_displacement.png"]


def potential_plot(
    points: np.ndarray, s: np.ndarray, phi: np.ndarray, outdir: Path, where: str
) -> str:
    """φ along a boundary part against its arc length `s` (a vertical side is a curve, not a
    vertical line); the ends' coordinates in the title. points (k, 2), s and phi (k,)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(s, phi, "o-", ms=3)
    ax.set_xlabel(f"arc length along {where} [m]")
    ax.set_ylabel(r"electric potential $\varphi$ [V]")
    a, b = points[0], points[-1]
    ax.set_title(
        f"potential along {where}, from ({a[0]:.4g}, {a[1]:.4g}) to ({b[0]:.4g}, {b[1]:.4g}) m"
    )
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(outdir / "potential.png", dpi=120)
    plt.close(fig)
    return "potential.png"


def friction_panel(ax, st: dict, ms: float = 2, fontsize: float = 7) -> str:
    """One panel of a friction sweep (and the first figure of `contact_plots`): the tangential
    multiplier (marker size `ms`) with its bound and the slip zones, and the tangential jump on
    a twin axis (`st` in the layout of `contact_plots`), the legend in `fontsize`; puts the
    tangent's sign convention under the figure; returns "stick N, slip M"."""
    _shade_slip(ax, st["s"], st["slip"])
    ax.plot(st["s"], st["lam_t"], "o-", ms=ms, label="multiplier")
    ax.plot(st["s"], st["g"], "k--", lw=1, label=bound_label(st))
    ax.plot(st["s"], -st["g"], "k--", lw=1)
    ax.set_xlabel(_label(st, "s_label"))
    ax.set_ylabel(_label(st, "lam_label"))
    ax2 = ax.twinx()
    ax2.plot(st["s"], st["jump_t"], "s-", ms=2, color="tab:orange", label="jump")
    ax2.set_ylabel(_label(st, "jump_label"), color="tab:orange")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="best", fontsize=fontsize)
    add_note(ax.figure, st.get("tangent_note", TAU_NOTE))
    return state_counts(st)


def sweep_figure(panels: list, draw, path: Path, title: str = "") -> list[str]:
    """One panel per (heading, model, sol) of `panels`, each drawn by draw(ax, model, sol),
    which returns a note appended to the heading; the same quantity on one scale across the
    panels (`share_scales`); returns the panels' titles."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4.3), squeeze=False)
    titles = []
    for ax, (heading, model, sol) in zip(axes[0], panels, strict=True):
        note = draw(ax, model, sol)
        titles.append(f"{heading}: {note}" if note else heading)
        ax.set_title(titles[-1], fontsize=9)
    fig.suptitle(title)
    _finish(fig)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return titles
