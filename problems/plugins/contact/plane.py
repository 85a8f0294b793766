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
from problems.scene.imported import require_curve
from vi_core import MixedVI, Solution
from vi_core import states as node_states

from ..contract import check_meshed
from . import electrical as electrical_contact
from . import errors, interface, plane_output, warm_starts
from . import extremes as contact_extremes
from . import model as contact_model
from .curve_contact import from_scene
from .interface import Interface
from .model import BodiesModel
from .scene_model import ContactScene, count, update  # noqa: F401 (contract)

NAME = "contact"  # the unified plug-in (problems.plugins.contact); 2D front
DIMENSION = 2  # the models' `dimension` (`count` needs no model to tell it)
ALIAS = "piezo_contact"  # its former name, still accepted (registry.ALIASES)
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


__getattr__ = contact_model.moved_names(
    __name__,
    {
        "PlaneScene": ("problems.plugins.contact.scene_model", "ContactScene"),
        "ContactSection": ("problems.plugins.contact.scene_model", "ContactSection"),
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
    if contact is not None:
        model.warnings += plane_output.interface_warnings(contact)
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
def contact_state(model: Model, sol: Solution) -> dict:
    """Per-node contact quantities along Γ3 and the Lemma 4.2 check.

    The arrays "s", "points", "lam_t", "g", "jump_t", "ut_slave", "slip", "touch_t" (and
    "ut_master") are per tangential multiplier row (`Interface.rows_t`), "s_n", "lam_n",
    "touch", "u_n", "gap" per normal row. "g" is the friction radius of the solution (g; unilateral
    Tresca: g where the node is not open, 0 elsewhere; Coulomb: F·λ_n). States follow from the
    answer by one rule (`vi_core.states`: multiplier margin and gap/slip, thresholds scaled by
    the achieved residual): "state" per tangential row (stick, slip, open or ambiguous),
    "normal_state" per normal row (touch, open or ambiguous); "slip" marks the slip nodes,
    "touch" ("touch_t") the nodes with touch evidence (every node for bilateral contact);
    "u_n" and "gap" (unilateral
    only) are the normal jump [u]_n and the initial gap gap₀ (the remaining gap is their
    difference), "pressure" the pressure scale (largest λ_n or elastic stress). Lemma 4.2
    reads λᵀ(B u − gap₀) = Σ_k ρ_k W_k|[u]_τ,k| (normal complementarity makes the normal part
    0).
    """
    c = model.contact
    lam_n, lam_t = c.normal(sol.lam), c.tangential(sol.lam)
    radius = c.bound(sol.lam)[c.rows_t]  # (N_t,) the friction radius at λ
    W_n, W_t = c.W_n[c.rows_n], c.W_t[c.rows_t]  # (N_n,), (N_t,) the rows' ∫φ̃_k
    j = interface.jumps(model, sol, radius, lambda: W_n.min())
    Bu, th = j.Bu, j.th  # Bu: W_k·[u]_n, W_k·[u]_τ in B_full's row order
    jump_t = c.tangential(Bu) / W_t  # nodal tangential (mortar) jump
    nodes = c.tr.nodes[c.rows_t]
    u_s = j.x_full[c.slave.u_dofs(nodes)]  # (N_t, 2)
    ut_s = np.einsum("ij,ij->i", u_s, c.tr.tangents[c.rows_t])
    normal = np.full(c.tr.size, "touch", dtype=object)  # bilateral: every node touches
    if c.law == "unilateral":
        normal[c.rows_n] = node_states.normal_states(lam_n, (c.gap0 - c.normal(Bu)) / W_n, th)
    touch = normal[c.rows_n] == "touch"  # (N_n,)
    touch_t = normal[c.rows_t] == "touch"  # (N_t,)
    rho = radius * (normal[c.rows_t] != "open")  # (N_t,); an open node has no friction
    tang = node_states.tangential_states(lam_t, rho, c.tangential(j.Bi) / W_t, th)
    labels = node_states.node_states(normal[c.rows_t], tang)  # (N_t,)
    slip = labels == "slip"
    weights = rho * W_t  # (N_t,) ∫ρφ̃_k (bilateral: g_weights)
    g_abs = float(np.sum(weights * np.abs(c.tangential(j.Bi) / W_t)))
    state = {
        "s": c.tr.s[c.rows_t],
        "points": c.slave.mesh.points[nodes],
        "s_n": c.tr.s[c.rows_n],
        "lam_n": lam_n,
        "lam_t": lam_t,
        "g": rho,
        "jump_t": jump_t,
        "ut_slave": ut_s,
        "slip": slip,
        "state": labels,
        "touch": touch,
        "touch_t": touch_t,
        "normal_state": normal[c.rows_n],
        **interface.lemma_4_2(sol.lam, j, g_abs, float(np.sum(weights))),
        "friction": c.friction,  # the bound's name in plots and tables (tresca: g, coulomb: Fλ_n)
    }
    if c.law == "unilateral":
        state["pressure"] = j.pressure  # the pressure scale
        state["u_n"] = c.normal(Bu) / W_n  # (N_n,) normal (mortar) jump [u]_n
        state["gap"] = c.gap0 / W_n  # (N_n,) initial gap
    if c.master_proj is not None:
        state["ut_master"] = c.master_proj @ j.x_full
    return state


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
postprocess = plane_output.postprocess  # result files and summary entries
step_output = plane_output.step_output  # one load step's files
contact_table = plane_output.contact_table  # contact.csv's rows (signorini's too)


def draw(ax, model: Model, sol: Solution) -> str:
    """A panel of `mixvi figures`: λ·τ with ±g, slip zones and the tangential jump along Γ3."""
    if model.contact is None:
        return "no contact interface"
    return plots.friction_panel(ax, contact_state(model, sol))


incremental = contact_model.incremental


from .error_estimate import estimate as _estimate  # noqa: E402 (issue 32)

estimate = partial(_estimate, SCENE_MODEL)  # a posteriori error indicators per cell
