"""What the command tests on `electrical_block` share: the closed-form check of an answer and
the fault of a command that drops the electrical contact condition.

The scene is a BaTiO3 block in uniaxial strain on a conductive foundation; its bottom
potential and pressure have a closed form (`piezo_extremes.uniaxial_electrical_defect`), 600 V
away from the insulating answer. A command solves the scene's real problem when it solves
through `problems.pipeline.solve_model` (the plug-in's outer fixed point on the conductances);
`drop_electrical` replaces that entry point by a solve of the insulating VI `model.vi`, which is
what every command but `mixvi solve` did before."""

from __future__ import annotations

import problems.pipeline as pipeline
import vi_core
from problems.plugins.contact.extremes import ELECTRICAL_MATCH, uniaxial_electrical_defect

SCENE = "electrical_block"


def defect(model, sol) -> float:
    """The larger relative defect of φ and λ_n on Γ3 against the uniaxial closed form."""
    return max(uniaxial_electrical_defect(model, sol).values())


def matches(model, sol) -> bool:
    """The answer is the closed form's (conductive or grounded, within ELECTRICAL_MATCH)."""
    return defect(model, sol) <= ELECTRICAL_MATCH


def drop_electrical(monkeypatch) -> None:
    """The fault: every command's solve of the scene's model becomes the insulating solve."""
    monkeypatch.setattr(
        pipeline, "solve_model", lambda plugin, model, **o: vi_core.solve(model.vi, **o)
    )
