"""The a posteriori error estimate of a solved model (the plug-in's optional `estimate`): its
files and summary entries (`estimate_output`), and its totals (`totals`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fem.io import write_vtu
from problems.plugins.contract import Indicator
from vi_core import Solution


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
