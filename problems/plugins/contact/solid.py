"""The 3D front of the contact plug-in: elastic or piezoelectric 3D bodies in bilateral
contact with Tresca friction, or in unilateral contact with Tresca (where touching) or Coulomb
friction discs. Its build, contact state, result files and contract declarations; the contact
interface itself (surface, frames, crosspoint rules, rows) is `surface_contact`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

from problems.scene import Scene
from problems.scene.fields import renamed
from vi_core import Solution

from . import errors, output, warm_starts
from . import extremes as contact_extremes
from . import model as contact_model
from .contact_state import contact_state as one_contact_state
from .model import BodiesModel
from .scene_model import ContactScene, count, update  # noqa: F401 (contract)
from .surface_contact import from_scene

NAME = "contact"  # the unified plug-in (problems.plugins.contact); 3D front
DIMENSION = 3  # the models' `dimension` (`count` needs no model to tell it)
DESCRIPTION = (
    "elastic/piezoelectric 3D bodies in bilateral Tresca or unilateral Tresca/Coulomb contact "
    "(friction discs)"
)
CONTRACT = 2


@dataclass
class Model(BodiesModel):
    """A built 3D scene: the mixed VI plus what post-processing needs."""

    dimension: int = DIMENSION


SCENE_MODEL = ContactScene  # one scene model for 2D and 3D (`scene_model`)


__getattr__ = renamed(
    __name__,
    {
        "SolidScene": "problems.plugins.contact.scene_model.ContactScene",
        "ContactSection": "problems.plugins.contact.scene_model.ContactSection",
    },
)


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model (meshes, assembly, Dirichlet reduction, contact rows, MixedVI); a
    SceneError raised while building names the scene file."""
    return contact_model.built(_build, scene, level)


def _build(scene: Scene, level: int | None) -> Model:
    spec = scene.validated(SCENE_MODEL, DIMENSION)
    return contact_model.assemble(spec, scene, level, from_scene, Model)


incremental = contact_model.incremental


# ------------------------------------------------------------------ post-processing
contact_state = one_contact_state  # the state of a solution (`contact_state`), 3D layout


postprocess = output.postprocess  # result files and summary entries (2D and 3D: `output`)
step_output = output.step_output  # one load step's files
contact_table = output.contact_table  # contact.csv's rows


# ------------------------------------------------------------------ contract v2 declarations
fields = contact_model.fields  # nodal fields by name
mesh_size = contact_model.mesh_size  # h of the built level
SWEEP = contact_model.friction_sweep("g_sweep3d.png", "F_sweep3d.png")
NORMS = errors.REFERENCE_NORMS[DIMENSION]  # against a finer level: reference_errors
EXACT_NORMS = errors.EXACT_NORMS  # against the scene's [exact] table: exact_errors
exact_errors = partial(errors.exact_errors, SCENE_MODEL, contact_state)
reference_errors = partial(errors.reference_errors, contact_state)
warm_start = partial(warm_starts.over_surface, contact_state)  # nested iteration
extremes = contact_extremes.rows_3d


def draw(ax, model: Model, sol: Solution) -> str:
    """A panel of `mixvi figures`: the stick/slip map of the contact surface."""
    if model.contact is None:
        return "no contact interface"
    st = contact_state(model, sol)
    uv, _, _ = output.chart(model)
    for s, col in (("stick", "tab:blue"), ("slip", "tab:red")):
        sel = st["state"] == s
        ax.scatter(uv[sel, 0], uv[sel, 1], s=8, color=col, label=f"{s} ({int(sel.sum())})")
    ax.set_aspect("equal")
    ax.legend(fontsize=7)
    return f"slip {int(st['slip'].sum())} of {int(st['has_t'].sum())} nodes"
