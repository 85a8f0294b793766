"""The 2D front of the contact plug-in: elasto-piezoelectric bodies in bilateral contact with
Tresca friction (Problem 4.1) or unilateral Tresca/Coulomb contact. Its build (with the
electrical contact of [contact.electrical]), solve, contact state and contract declarations;
the contact interface itself (trace, crosspoint rules, rows) is `curve_contact`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

import vi_core
from problems.output import plots
from problems.scene import Scene
from problems.scene.fields import renamed
from problems.scene.imported import require_curve
from vi_core import MixedVI, Solution

from ..contract import check_meshed
from . import electrical as electrical_contact
from . import errors, output, warm_starts
from . import extremes as contact_extremes
from . import model as contact_model
from .contact_state import contact_state as one_contact_state
from .curve_contact import from_scene
from .error_estimate import estimate as _estimate
from .interface import Interface
from .model import BodiesModel
from .scene_model import ContactScene, count, update  # noqa: F401 (contract)

NAME = "contact"  # the unified plug-in (problems.plugins.contact); 2D front
DIMENSION = 2  # the models' `dimension` (`count` needs no model to tell it)
LOCKING_RATIO = 50.0  # λ_max/λ_min of the Voigt C; isotropic ν = 0.48 gives 50
DESCRIPTION = (
    "elasto-piezoelectric bodies in bilateral Tresca or unilateral Tresca/Coulomb contact "
    "(dual mortar multipliers)"
)


@dataclass
class Model(BodiesModel):
    """A built scene: the mixed VI plus what post-processing needs."""

    dimension: int = DIMENSION
    electrical: electrical_contact.Coupling | None = None  # [contact.electrical], if given

    def contact_state(self, sol: Solution) -> dict:
        """`contact_state(self, sol)` (for modules that this one imports)."""
        return contact_state(self, sol)


SCENE_MODEL = ContactScene  # one scene model for 2D and 3D (`scene_model`)


__getattr__ = renamed(
    __name__,
    {
        "PlaneScene": "problems.plugins.contact.scene_model.ContactScene",
        "ContactSection": "problems.plugins.contact.scene_model.ContactSection",
    },
)


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model (mesh, assembly, Dirichlet reduction, contact, MixedVI).

    Any SceneError raised while building names the scene file.
    """
    return contact_model.built(_build, scene, level)


def _build(scene: Scene, level: int | None) -> Model:
    return build_model(scene.validated(SCENE_MODEL, DIMENSION), scene, level)


def build_model(
    spec: ContactScene, scene: Scene, level: int | None, model_class: type[Model] = Model
) -> Model:
    """The Model (of `model_class`, a subclass of Model) of a validated scene model `spec`
    (of `scene`); signorini builds its scenes through it."""
    options = {"potential_along": None}
    model = contact_model.assemble(spec, scene, level, from_scene, model_class, options)
    ct, contact, vi = spec.contact, model.contact, model.vi
    along = None if spec.output is None else spec.output.potential_along
    if along is not None:
        bname, part = along.split(".", 1)
        key = spec.output.key("potential_along")
        mesh = next(b.mesh for b in model.bodies if b.name == bname)
        check_meshed(mesh, [(key, part)])
        require_curve(mesh, part, key, along)
        model.options["potential_along"] = (bname, part)
    if ct is not None and ct.electrical is not None:
        model.electrical = _electrical(ct.electrical, contact, vi, model.free, model.values)
    for b in model.bodies:
        ev = np.linalg.eigvalsh(b.material.C)
        if ev[-1] / ev[0] > LOCKING_RATIO:
            model.warnings.append(
                f"body {b.name!r}: nearly incompressible material (eigenvalue ratio of C "
                f"{ev[-1] / ev[0]:.3g} > {LOCKING_RATIO:g}); lowest-order elements lock — "
                "displacements are underestimated on coarse meshes"
            )
    return model


def _electrical(
    e: electrical_contact.ElectricalSection,
    contact: Interface,
    vi: MixedVI,
    free: np.ndarray,
    values: np.ndarray | None = None,
) -> electrical_contact.Coupling:
    """The fixed point's data: φ unknowns and normal multipliers of the slave trace nodes, and
    with a piezoelectric master body its mortar mean Π φ_m (on the unknowns, and the part of
    the jump from prescribed potentials); a master without potential is a conductor at φ_F."""
    tr, slave = contact.tr, contact.slave
    nodes = contact.rows_n  # trace indices carrying λ_n (index j of λ)
    full = slave.phi_dofs(tr.nodes[nodes])  # (N,)
    pos = np.searchsorted(free, full)
    found = (pos < free.size) & (free[np.minimum(pos, free.size - 1)] == full)
    kappa_max = float(np.linalg.eigvalsh(slave.material.kappa)[-1])
    master, fixed, phi_F = None, None, float(e.phi_F)
    if contact.master_phi is not None:
        P = contact.master_phi  # (N, n_full)
        is_free = np.zeros(P.shape[1], dtype=bool)
        is_free[free] = True
        known = np.where(is_free, 0.0, values)  # (n_full,) prescribed values only
        master = P[:, free].tocsr()
        fixed = np.where(found, 0.0, values[full]) - P @ known  # (N,)
        phi_F = 0.0  # the master's potential replaces the foundation's
    return electrical_contact.Coupling(
        master=master,
        fixed=fixed,
        vi0=vi,
        phi=np.where(found, pos, -1),
        normal=contact.idx_n,
        weights=tr.weights[nodes],
        law=e.law_of(kappa_max, float(tr.measures.max())),
        phi_F=phi_F,
        max_iter=int(e.max_iter),
        tol=float(e.tol),
    )


def solve(model: Model, **options) -> Solution:
    """`vi_core.solve(model.vi, **options)`, or with a conductive or grounded
    [contact.electrical] the outer fixed point on k (`electrical_contact.solve_coupled`);
    model.vi becomes the last frozen problem."""
    c = model.electrical
    if c is None or c.law.kind == "none":
        return vi_core.solve(model.vi, **options)
    sol, model.vi = electrical_contact.solve_coupled(c, **options)
    return sol


def problem_at(model: Model, sol: Solution) -> MixedVI:
    """The mixed VI `sol` must solve (`problems.pipeline.problem_at`): with a conductive or
    grounded [contact.electrical] the insulating VI plus the Robin term frozen at the
    conductances k(λ_n) of `sol` itself — a fixed point of the outer iteration solves it —
    else `model.vi`."""
    c = model.electrical
    if c is None or c.law.kind == "none":
        return model.vi
    return c.frozen(c.conductances(sol.lam))


warm_start = warm_starts.along_curve  # nested iteration (`warm_start`)


# ------------------------------------------------------------------ post-processing
contact_state = one_contact_state  # the state of a solution (`contact_state`), 2D layout


# ------------------------------------------------------------------ contract v2 declarations
fields = contact_model.fields  # nodal fields by name
mesh_size = contact_model.mesh_size  # h of the built level
CONTRACT = 2
SWEEP = contact_model.friction_sweep("fig_5_4.png", "F_sweep.png")
NORMS = errors.REFERENCE_NORMS[DIMENSION]  # u_H1, phi_H1, phi_L2, lam (Theorem 4.1)
EXACT_NORMS = errors.EXACT_NORMS  # with u_L2
exact_errors = partial(errors.exact_errors, SCENE_MODEL, contact_state)
reference_errors = partial(errors.reference_errors, contact_state)
extremes = contact_extremes.rows_2d
postprocess = output.postprocess  # result files and summary entries (2D and 3D: `output`)
step_output = output.step_output  # one load step's files
contact_table = output.contact_table  # contact.csv's rows (signorini's too)


def draw(ax, model: Model, sol: Solution) -> str:
    """A panel of `mixvi figures`: λ·τ with ±g, slip zones and the tangential jump along Γ3."""
    if model.contact is None:
        return "no contact interface"
    return plots.friction_panel(ax, contact_state(model, sol))


incremental = contact_model.incremental


estimate = partial(_estimate, SCENE_MODEL)  # a posteriori error indicators per cell
