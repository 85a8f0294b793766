"""Plug-in `contact`: elastic or piezoelectric bodies in bilateral Tresca or unilateral
Tresca/Coulomb contact with dual mortar multipliers, in 2D and in 3D.

One plug-in, one registered name, one scene language: `[scene] plugin = "contact"`, one scene
model (`scene_model.ContactScene`) whose dimension is the bodies' geometries'
(`dimension.scene_dimension`). Its two fronts are the modules `plane` (2D: a contact node
carries a normal and one tangential multiplier, the friction interval [−g, g]; the trace of a
boundary curve is `curve_contact`'s) and `solid` (3D: a normal and up to two tangential ones,
the friction disc |λ_t| ≤ g; the trace of a surface is `surface_contact`'s); they share the
bodies and their assembly (`bodies`, `fields`, `body_output`), the model and its mixed VI
(`model`), the contact law's scene keys and sets (`law`), the contact interface itself (one
`Interface` for 2D and 3D with its row order and Λ: `interface`; its rows built once:
`rows`; the contact state of a solution and the Lemma 4.2 identity: `contact_state`; node
names, summaries and warnings: `reports`), the error norms (`errors`), the checks
(`checks`), the electrical contact (`electrical`), the load-path and warm-start transfers
(`problems.plugins.transfer`, `warm_starts`), the two-body geometry checks (`separation`), the
manufactured balance (`balance`) and the result files (`output`: one writer for both
dimensions, one contact table per slave node, `problems.output.results.ContactTable`).
Each front declares the whole contract v2 with NAME = "contact"; `registry.for_scene` hands a
scene the front of its dimension (`front`), and this module answers for the plug-in as a whole
where no scene is at hand (`mixvi schema`, `mixvi extremes`, listings).

The former names `piezo_contact` (2D) and `contact3d` (3D) stay accepted in scenes
(`registry.ALIASES`, with a one-line notice on stderr) and fix the dimension.
"""

from __future__ import annotations

from typing import Any

from problems.scene import Scene

from . import plane, solid
from .dimension import scene_dimension
from .scene_model import ContactScene

NAME = "contact"
CONTRACT = 2
DESCRIPTION = (
    "elastic/piezoelectric bodies in 2D or 3D, bilateral Tresca or unilateral Tresca/Coulomb "
    "contact (dual mortar multipliers; friction intervals in 2D, discs in 3D)"
)
FRONTS = {2: plane, 3: solid}


def front(scene: Scene) -> Any:
    """The front (`plane` or `solid`) of `scene`'s dimension (SceneError if its bodies mix
    2D and 3D geometries)."""
    return FRONTS[scene_dimension(scene.data, scene.path)]


SCENE_MODEL = ContactScene  # one scene model, 2D and 3D (`scene_model`)


def build(scene: Scene, level: int | None = None) -> Any:
    """Scene → Model of its dimension's front."""
    return front(scene).build(scene, level)


def postprocess(model: Any, sol: Any, outdir: Any) -> dict:
    """The front's post-processing of a model it built."""
    return FRONTS[model.dimension].postprocess(model, sol, outdir)


def extremes() -> list:
    """The extreme rows of both fronts (`mixvi extremes`)."""
    return [*plane.extremes(), *solid.extremes()]
