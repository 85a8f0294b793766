"""Figures of `mixvi sweep`: one output against the first swept parameter, one line per
combination of the other parameters (a parameter whose values are not all numbers is drawn
at positions 0, 1, ... labelled with its values)."""

from __future__ import annotations

from pathlib import Path

from .plots import pyplot


def _number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def plot_output(result: dict, key: str, path: Path) -> None:
    """Output `key` (a dotted key of the cases' `outputs`) of sweep.json's `result` against
    its first parameter; cases without the output (failed) are left out of their line."""
    keys = list(result["parameters"])
    x_key, others = keys[0], keys[1:]
    xs = result["parameters"][x_key]
    numeric = all(_number(v) for v in xs)
    pos = {repr(v): (v if numeric else i) for i, v in enumerate(xs)}
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5), constrained_layout=True)
    lines: dict[tuple, list[tuple]] = {}
    for r in result["cases"]:
        y = r["outputs"].get(key)
        group = tuple(r["set"][k] for k in others)
        lines.setdefault(group, [])
        if _number(y):
            lines[group].append((pos[repr(r["set"][x_key])], y))
    for group, pts in lines.items():
        pts.sort()
        label = ", ".join(f"{k} = {v:.4g}" if _number(v) else f"{k} = {v}" for k, v in
                          zip(others, group, strict=True)) or None  # fmt: skip
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=label)
    if not numeric:
        ax.set_xticks(range(len(xs)), [str(v) for v in xs])
    ax.set_xlabel(x_key)
    ax.set_ylabel(key)
    ax.grid(True, alpha=0.3)
    if others:
        ax.legend(fontsize=8)
    ax.set_title(f"{result['scene']} (level {result['level']}): {key} against {x_key}", fontsize=9)
    fig.savefig(path, dpi=120)
    plt.close(fig)
