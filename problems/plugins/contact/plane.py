"""Plug-in: elasto-piezoelectric bodies in bilateral contact with Tresca friction (Problem 4.1).

Dual (biorthogonal) multipliers on the slave side Γ3: λ_h = Σ_k γ_k ψ̃_k n_k + Σ_k α_k ψ̃_k τ_k,
and Λ_h = product(Free(N_n), Box(−g_k, g_k)) with g_k = ∫g φ̃_k / ∫φ̃_k (docs/design.md §3; φ̃_k = φ_k
unless an end treatment merged a neighbour in). With a rigid foundation the constraint rows are
Σ_j Ds_kj n_kᵀu_j (normal) and the same with τ_k (tangential); with a master body they act on
the mortar jump Ds u_s − M u_m (`fem.mortar`).

Contact rules (README "Contact interfaces"):

- crosspoints: a slave node whose displacement is fully prescribed carries no multiplier; at a
  node where one component is prescribed and that direction is the contact tangent (normal),
  only the tangential (normal) multiplier is dropped; any other partially prescribed node is
  refused, per node. `[contact] ends` = "merge" (default, Wohlmuth's end-node modification of
  the dual basis) or "keep" (`fem.facets.multiplier_basis`).
- coverage: a slave node carries a multiplier only if the master lies behind its whole support;
  the others are left free and listed (warning, summary `contact.uncovered_nodes`); if no node
  is covered the scene is refused.
- patch test: `contact.mortar_patch_defect` = max_k |Σ_j Ds_kj − Σ_j M_kj| / Σ_j Ds_kj over the
  multiplier rows (0 by construction for the rigid foundation, which has no master side).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Annotated, Literal

import numpy as np
import scipy.sparse as sp
from pydantic import Field, model_validator

import vi_core
from fem.facets import ENDS, Trace, dual_mass, facet_integrals, multiplier_basis, trace
from fem.mesh import Mesh
from problems.errors import SceneError
from problems.output import plots
from problems.scene import Scene, SceneModel, Section
from problems.scene.exact import ExactSection
from problems.scene.fields import Text
from problems.scene.imported import require_curve
from problems.scene.model import head, refuse
from vi_core import Box, Free, MixedVI, NonNegative, Solution, product
from vi_core import states as node_states

from ..contract import check_meshed
from . import checks, errors, interface, plane_output, separation, warm_starts
from . import electrical as electrical_contact
from . import extremes as contact_extremes
from . import law as contact_law
from . import model as contact_model
from .bodies import Body, BodySection
from .law import FRICTIONS, LAWS
from .model import BodiesModel, build_bodies, interface_references, reference

NAME = "contact"  # the unified plug-in (problems.plugins.contact); 2D front
DIMENSION = 2  # the models' `dimension` (`count` needs no model to tell it)
ALIAS = "piezo_contact"  # its former name, still accepted (registry.ALIASES)
LOCKING_RATIO = 50.0  # λ_max/λ_min of the Voigt C; isotropic ν = 0.48 gives 50
DESCRIPTION = (
    "elasto-piezoelectric bodies in bilateral Tresca or unilateral Tresca/Coulomb contact "
    "(dual mortar multipliers)"
)
# A prescribed displacement component at a contact node counts as along the contact normal or
# tangent if the sine of the angle between them is at most ALIGN_TOL (a roller on a side
# perpendicular to a flat contact: exactly 0).
ALIGN_TOL = 1e-10


@dataclass
class Contact:
    """The contact interface Γ3: slave trace, master (None = rigid), multiplier rows, bounds.

    Multipliers: λ = (γ, α), γ on the normal rows `rows_n`, α on the tangential rows `rows_t`
    (trace indices of the nodes carrying them; all nodes unless crosspoints or uncovered nodes
    dropped some), with bases Q_n, Q_t in the segment-local dual functions.
    """

    slave: Body
    slave_part: str
    tr: Trace  # slave trace
    master: Body | None
    master_part: str | None
    ends: str  # "merge" or "keep" (fem.facets.multiplier_basis)
    rows_n: np.ndarray  # (N_n,) trace indices carrying a normal multiplier
    rows_t: np.ndarray  # (N_t,) trace indices carrying a tangential multiplier
    Q_n: sp.csr_matrix  # (N_n, 2·n_seg) normal multiplier basis
    Q_t: sp.csr_matrix  # (N_t, 2·n_seg) tangential multiplier basis
    W_n: np.ndarray  # (N_n,) row weights Σ_j Ds_kj = ∫φ̃_k of the normal rows
    W_t: np.ndarray  # (N_t,) the same for the tangential rows
    g: np.ndarray  # (N_t,) g_k = ∫gφ̃_k / ∫φ̃_k
    B_full: sp.csr_matrix  # (N_n + N_t, n_full): normal rows then tangential rows
    g_weights: np.ndarray  # (N_t,) ∫ g φ̃_k  (= g_k W_k)
    patch_defect: float  # max_k |Σ_j Ds_kj − Σ_j M_kj| / Σ_j Ds_kj (0 for a rigid master)
    uncovered: np.ndarray  # trace indices left without multiplier: no master behind them
    master_proj: sp.csr_matrix | None = None  # (N_t, n_full): u ↦ mortar-mean u_m·τ_k
    # (N_n, n_full): x ↦ mortar mean Σ_j M_kj φ_m,j / W_k of a piezoelectric master's potential
    master_phi: sp.csr_matrix | None = None
    law: str = LAWS[0]  # "bilateral" or "unilateral"
    friction: str = FRICTIONS[0]  # "tresca" or "coulomb"
    F: np.ndarray | None = None  # (N_t,) Coulomb F_k = ∫Fφ̃_k / ∫φ̃_k (friction = "coulomb")
    gap0: np.ndarray | None = None  # (N_n,) initial gap rows Σ_j Ds_kj gap(x_j) (unilateral)
    closed_gap: float = 0.0  # bilateral, two bodies: the largest initial gap it closes (m)
    idx_n: np.ndarray | None = None  # (N_n,) row of B_full (and λ) holding each normal row
    idx_t: np.ndarray | None = None  # (N_t,) the same for the tangential rows
    pairs: int = 0  # unilateral: rows 0 … 2·pairs − 1 of B_full are nodes [n, τ] interleaved

    @property
    def sizes(self) -> tuple[int, int]:
        """(N_n, N_t): numbers of normal and tangential multipliers."""
        return self.rows_n.size, self.rows_t.size

    def normal(self, v: np.ndarray) -> np.ndarray:
        """The normal rows (N_n,) of a vector in the row order of B_full (λ, B u)."""
        return v[self.idx_n]

    def tangential(self, v: np.ndarray) -> np.ndarray:
        """The tangential rows (N_t,) of a vector in the row order of B_full (λ, B u)."""
        return v[self.idx_t]

    def bound(self, lam: np.ndarray) -> np.ndarray:
        """(N_t,) the friction radius at the multiplier λ (B_full's row order): g (bilateral),
        g where λ_n > 0 and 0 elsewhere (unilateral Tresca), F·max(λ_n, 0) (Coulomb)."""
        return interface.friction_radius(self, lam, self.tr.size, self.rows_t)

    def Lambda(self):
        """Bilateral: Λ_h = Free(N_n) × Box(−g, g); unilateral: the contact set of the node
        pairs [n, τ] (`contact_law.pair_set`), NonNegative over the normal-only nodes."""
        n_n = self.rows_n.size
        if self.law == "bilateral":
            return product(Free(n_n), Box(-self.g, self.g))
        p = self.pairs  # every tangential row is paired with its node's normal row
        bound = self.F if self.friction == "coulomb" else self.g
        pairs = contact_law.pair_set(self.friction, bound, dim=2)
        return product(pairs, NonNegative(n_n - p)) if n_n > p else product(pairs)

    def gram_weights(self) -> np.ndarray:
        """(N_n + N_t,) h_k W_k per row of B_full (h_k the longer adjacent segment, W_k the
        nodal weight ∫φ_k): the diagonal of Y (`interface.multiplier_rows`)."""
        rows = np.empty(self.B_full.shape[0], dtype=int)  # trace index of each row of B_full
        rows[self.idx_n], rows[self.idx_t] = self.rows_n, self.rows_t
        return self.tr.node_sizes()[rows] * self.tr.weights[rows]


@dataclass
class Model(BodiesModel):
    """A built scene: the mixed VI plus what post-processing needs."""

    dimension: int = DIMENSION
    electrical: electrical_contact.Coupling | None = None  # [contact.electrical], if given

    def contact_state(self, sol: Solution) -> dict:
        """`contact_state(self, sol)` (for modules that this one imports)."""
        return contact_state(self, sol)


class ContactSection(contact_law.ContactLaw):
    """[contact]: slave and master boundaries (BODY.BOUNDARY, master "rigid" for a rigid
    foundation), the contact law (docs/coulomb.md, "Contact laws of the plug-ins"), and the
    multiplier end rule.

    law = "bilateral" (the paper's: the bodies stay in contact, λ_n of any sign) or
    "unilateral" (λ_n ≥ 0, gap ≥ 0, λ_n·gap = 0); friction = "tresca" (bound g, a field ≥ 0
    in Pa; with law = "unilateral" it acts only where the bodies touch) or "coulomb" (bound
    F·λ_n, F a field ≥ 0; unilateral only); gap = the initial normal distance to a rigid
    foundation (m, a field ≥ 0; unilateral only; two bodies take theirs from the geometry).
    """

    slave: Text
    master: Text = "rigid"
    ends: Literal[ENDS] = ENDS[0]
    electrical: electrical_contact.ElectricalSection | None = None


class OutputSection(Section):
    """[output]: potential_along = BODY.BOUNDARY (a plot of φ along it)."""

    potential_along: Text | None = None


Head = head(NAME, 1, ALIAS)


class PlaneScene(SceneModel):
    """A piezo_contact scene: bodies, optional contact interface, output and exact solution."""

    scene: Head
    bodies: Annotated[dict[str, BodySection], Field(min_length=1)]
    contact: ContactSection | None = None
    output: OutputSection | None = None
    exact: ExactSection | None = None  # read by `mixvi study`

    @model_validator(mode="after")
    def _references(self) -> PlaneScene:
        c = self.contact
        if c is not None:
            slave = interface_references(self.bodies, c)
            e = c.electrical
            if e is not None:
                if not self.bodies[slave].material.piezoelectric:
                    raise refuse(
                        ["contact", "electrical"], e.kind, "only with a piezoelectric slave body"
                    )
                piezo_master = c.master != "rigid" and (
                    self.bodies[c.master.split(".")[0]].material.piezoelectric
                )
                if piezo_master and e.kind != "insulating" and e.phi_F != 0.0:
                    raise refuse(
                        ["contact", "electrical", "phi_F"],
                        e.phi_F,
                        "0 (absent) with a piezoelectric master body: the charge flows into "
                        "the master, whose potential takes the foundation's place",
                    )
        if self.output is not None and self.output.potential_along is not None:
            field = ["output", "potential_along"]
            body, _ = reference(self.bodies, field, self.output.potential_along)
            if not self.bodies[body].material.piezoelectric:
                raise refuse(
                    field, self.output.potential_along, "a boundary of a piezoelectric body"
                )
        return self


SCENE_MODEL = PlaneScene


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model (mesh, assembly, Dirichlet reduction, contact, MixedVI).

    Any SceneError raised while building names the scene file.
    """
    return contact_model.built(_build, scene, level)


def _build(scene: Scene, level: int | None) -> Model:
    return build_model(scene.validated(SCENE_MODEL), scene, level)


def build_model(
    spec: PlaneScene, scene: Scene, level: int | None, model_class: type[Model] = Model
) -> Model:
    """The Model (of `model_class`, a subclass of Model) of a validated scene model `spec`
    (of `scene`); signorini builds its scenes through it."""
    level = spec.scene.level if level is None else level
    bodies: dict[str, Body] = build_bodies(spec, level)
    n_full = sum(b.size for b in bodies.values())
    contact = None
    ct = spec.contact
    if ct is not None:
        sname, slave_part = ct.slave.split(".", 1)
        slave, master, mpart = bodies[sname], None, None
        refs = [(ct.key("slave"), slave, slave_part)]
        if ct.master != "rigid":
            mname, mpart = ct.master.split(".", 1)
            master = bodies[mname]
            refs.append((ct.key("master"), master, mpart))
        for key, b, part in refs:
            check_meshed(b.mesh, [(key, part)])
            require_curve(b.mesh, part, key, f"{b.name}.{part}")
        contact = _contact(slave, slave_part, master, mpart, ct, n_full, level)
    options = {"potential_along": None, **spec.options()}
    if spec.output is not None and spec.output.potential_along is not None:
        bname, part = spec.output.potential_along.split(".", 1)
        key = spec.output.key("potential_along")
        check_meshed(bodies[bname].mesh, [(key, part)])
        require_curve(bodies[bname].mesh, part, key, spec.output.potential_along)
        options["potential_along"] = (bname, part)

    vi, free, values, rhs = contact_model.mixed_vi(
        list(bodies.values()),
        contact,
        {"scene": scene.name, "level": level},
        check=partial(checks.finite_data, contact=contact),
    )
    model = model_class(
        scene, level, list(bodies.values()), contact, vi, free, values, options, rhs=rhs
    )
    if ct is not None and ct.electrical is not None:
        model.electrical = _electrical(ct.electrical, contact, vi, free, values)
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
    contact: Contact,
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


def _carrying(slave: Body, part: str, tr: Trace) -> tuple[np.ndarray, np.ndarray]:
    """(carry_n, carry_t) per slave trace node: which multiplier components it carries.

    Crosspoint rules (module docstring); SceneError listing every unsupported node.
    """
    fixed = slave.fixed[slave.u_dofs(tr.nodes) - slave.offset]  # (N, 2); body-local dofs
    carry_n, carry_t = ~fixed.all(axis=1), ~fixed.all(axis=1)  # (N,) each
    bad = []
    for i in np.flatnonzero(fixed.any(axis=1) & ~fixed.all(axis=1)):
        c = int(np.flatnonzero(fixed[i])[0])
        n = tr.normals[i]
        if abs(n[c]) <= ALIGN_TOL:  # the prescribed direction e_c is the tangent
            carry_t[i] = False
        elif abs(n[1 - c]) <= ALIGN_TOL:  # e_c is the normal
            carry_n[i] = False
        else:
            angle = np.degrees(np.arccos(min(abs(n[c]), 1.0)))
            bad.append(
                f"{interface.node_at(slave, tr, i)}: only u_{'xy'[c]} is prescribed, a direction "
                f"{angle:.3g}° off the contact normal n = [{n[0]:.6g}, {n[1]:.6g}]"
            )
    if bad:
        raise SceneError(
            "contact.slave",
            f"{slave.name}.{part}",
            "contact nodes whose prescribed displacement is complete (clamped) or one component "
            "along the contact normal or tangent (a roller across or along Γ3); unsupported: "
            + "; ".join(bad)
            + ". A prescribed component at an angle to Γ3 would fight the contact multipliers:"
            " clamp these nodes (prescribe both components), free them, or move the side's "
            "roller so that its direction is the contact normal or tangent there",
        )
    return carry_n, carry_t


def _contact(
    slave: Body,
    part: str,
    master: Body | None,
    mpart: str | None,
    ct: ContactSection,
    n_full: int,
    level: int = 0,
) -> Contact:
    """The contact rows: normal Σ_j Ds_kj n_kᵀu_s,j − Σ_j M_kj n_kᵀu_m,j (M = 0 for a rigid
    foundation), then the same with τ_k, for the multiplier rows of each component; with
    law = "unilateral" the rows of a node are put side by side [n, τ] (vi_core.coulomb) and the
    initial gap rows Σ_j Ds_kj gap(x_j) are built (gap: the scene's field for a rigid
    foundation, the distance along n_j to the master polyline for two bodies)."""
    from fem.mortar import COVER_TOL, mortar_coupling, patch_defect

    unilateral = ct.law == "unilateral"
    tr = trace(slave.mesh, part)
    carry = _carrying(slave, part, tr)
    if unilateral and (carry[1] & ~carry[0]).any():
        i = int(np.flatnonzero(carry[1] & ~carry[0])[0])
        raise SceneError(
            "contact.law",
            "unilateral",
            f"contact nodes free to separate; {interface.node_at(slave, tr, i)} has its normal "
            "displacement prescribed (a roller across Γ3): with unilateral contact prescribe "
            "both components there or none (or use law = 'bilateral')",
        )
    if not (carry[0] | carry[1]).any():
        raise SceneError(
            "contact.slave",
            f"{slave.name}.{part}",
            "a contact boundary with nodes whose displacement is not fully prescribed: every "
            "node of this one is clamped by a [[displacement]] part, so no contact remains; "
            "remove the Dirichlet condition on it or the [contact] table",
        )
    n_seg = tr.facets.shape[0]
    uncovered_local = np.zeros(2 * n_seg, dtype=bool)
    gap_nodes = np.zeros(tr.size)  # (N,) initial normal gap at the slave nodes
    closed = 0.0  # the initial gap bilateral contact closes
    if master is not None:
        if unilateral:
            gap_nodes = separation.initial_gap(slave, part, tr, tr.normals, master, mpart, level)
        else:
            closed = separation.check_separation(slave, part, tr, tr.normals, master, mpart, level)
        reach = 1.0 + float(np.max(gap_nodes, initial=0.0) / tr.measures.min())
        mort = mortar_coupling(slave.mesh, part, master.mesh, mpart, reach=reach)
        assert np.array_equal(tr.nodes, mort.slave_nodes)
        uncovered_local = np.repeat(mort.coverage < 1.0 - COVER_TOL, 2)  # (2 n_seg,) (fem.mortar)
        mdofs = master.u_dofs(mort.master_nodes)  # (nm, 2)
    else:
        gap_nodes = interface.rigid_gap(ct.gap, slave.mesh.points[tr.nodes])
    Dloc = dual_mass(tr)  # (2 n_seg, N)
    bfun = ct.g if ct.friction == "tresca" else ct.F
    gloc = _friction_local(slave.mesh, tr, bfun).ravel()  # (2 n_seg,)
    sdofs = slave.u_dofs(tr.nodes)  # (N, 2)
    uncovered = np.zeros(tr.size, dtype=bool)
    blocks, rows_c, Q_c, defects, offset = [], [], [], [0.0], 0
    for comp, vec in ((0, tr.normals), (1, tr.tangents)):
        Q = multiplier_basis(tr, carry[comp], ct.ends)
        rows = np.flatnonzero(carry[comp])
        bad = (Q @ uncovered_local) > 0  # some of the row's support has no master behind it
        uncovered[rows[bad]] = True
        Q, rows = Q[~bad], rows[~bad]
        Ds = (Q @ Dloc).tocoo()
        parts = [(Ds, sdofs, 1.0)]
        if master is not None:
            M = (Q @ mort.M).tocoo()
            parts.append((M, mdofs, -1.0))
            if rows.size:
                defects.append(float(patch_defect(Q @ Dloc, Q @ mort.M).max()))
        for mat, dofs, sign in parts:
            for c in range(2):
                r = offset + mat.row
                blocks.append((r, dofs[mat.col, c], sign * mat.data * vec[rows[mat.row], c]))
        rows_c.append(rows)
        Q_c.append(Q)
        offset += rows.size
    if offset == 0:
        raise SceneError(
            "contact.master",
            f"{master.name}.{mpart}" if master is not None else "rigid",
            f"a master boundary behind the slave boundary {slave.name}.{part}: no slave node "
            f"has the master behind its support (nodes {tr.nodes.tolist()}); make the two "
            "boundaries face each other and overlap",
        )
    r, c, v = (np.concatenate(x) for x in zip(*blocks, strict=True))
    B = sp.csr_matrix((v, (r, c)), shape=(offset, n_full))
    Q_t, rows_n, rows_t = Q_c[1], rows_c[0], rows_c[1]
    if unilateral and not np.isin(rows_t, rows_n).all():
        i = int(rows_t[~np.isin(rows_t, rows_n)][0])
        raise SceneError(
            "contact.master",
            f"{master.name}.{mpart}" if master is not None else "rigid",
            f"a master behind the normal multiplier of every slave node with a tangential one "
            f"(unilateral contact); {interface.node_at(slave, tr, i)} has none",
        )
    W_n, W_t = (np.asarray((Q @ Dloc).sum(axis=1)).ravel() for Q in Q_c)  # ∫φ̃_k per row
    gw = Q_t @ gloc  # (N_t,) ∫gφ̃_k (Coulomb: ∫Fφ̃_k)
    n_n, n_t = rows_n.size, rows_t.size
    idx_n, idx_t, pairs = np.arange(n_n), n_n + np.arange(n_t), 0
    if unilateral:  # nodes [n, τ] side by side, then the nodes with a normal row only
        paired = np.isin(rows_n, rows_t)  # (N_n,); every tangential row is paired (above)
        pairs = n_t
        idx_n = np.empty(n_n, dtype=int)
        idx_n[paired] = 2 * np.arange(pairs)
        idx_n[~paired] = 2 * pairs + np.arange(n_n - pairs)
        idx_t = 2 * np.arange(pairs) + 1
        order = np.empty(n_n + n_t, dtype=int)  # B_full row → row of B built above
        order[idx_n], order[idx_t] = np.arange(n_n), n_n + np.arange(n_t)
        B = B[order]
    gap0 = (Q_c[0] @ Dloc) @ gap_nodes if unilateral else None  # (N_n,)
    proj = None
    if master is not None:  # mortar mean of u_m·τ_k over the row's support
        M = (Q_t @ mort.M).tocoo()
        pv = [M.data * tr.tangents[rows_t[M.row], c] / W_t[M.row] for c in range(2)]
        proj = sp.csr_matrix(
            (
                np.concatenate(pv),
                (np.tile(M.row, 2), np.concatenate([mdofs[M.col, c] for c in range(2)])),
            ),
            shape=(rows_t.size, n_full),
        )
    master_phi = None
    if master is not None and master.has_potential:  # normal rows: Σ_j M_kj φ_m,j / W_k
        M = (Q_c[0] @ mort.M).tocoo()
        master_phi = sp.csr_matrix(
            (M.data / W_n[M.row], (M.row, master.phi_dofs(mort.master_nodes)[M.col])),
            shape=(rows_n.size, n_full),
        )
    return Contact(
        slave=slave,
        slave_part=part,
        tr=tr,
        master=master,
        master_part=mpart,
        ends=ct.ends,
        rows_n=rows_n,
        rows_t=rows_t,
        Q_n=Q_c[0],
        Q_t=Q_t,
        W_n=W_n,
        W_t=W_t,
        g=gw / W_t if ct.friction == "tresca" else np.zeros(n_t),
        B_full=B,
        g_weights=gw if ct.friction == "tresca" else np.zeros(n_t),
        patch_defect=max(defects),
        uncovered=np.flatnonzero(uncovered),
        master_proj=proj,
        master_phi=master_phi,
        law=ct.law,
        friction=ct.friction,
        F=gw / W_t if ct.friction == "coulomb" else None,
        gap0=gap0,
        closed_gap=closed,
        idx_n=idx_n,
        idx_t=idx_t,
        pairs=pairs,
    )


def _friction_local(mesh: Mesh, tr: Trace, gfun) -> np.ndarray:
    """(n_seg, 2) ∫_e g φ_{e,a} ds (g ≥ 0 checked at every quadrature point: `checked_bound`;
    g is the Tresca bound or the Coulomb coefficient F)."""
    return facet_integrals(mesh, tr, interface.checked_bound(gfun))


warm_start = warm_starts.along_curve  # nested iteration (`warm_start`)


# ------------------------------------------------------------------ post-processing
def contact_state(model: Model, sol: Solution) -> dict:
    """Per-node contact quantities along Γ3 and the Lemma 4.2 check.

    The arrays "s", "points", "lam_t", "g", "jump_t", "ut_slave", "slip", "touch_t" (and
    "ut_master") are per tangential multiplier row (`Contact.rows_t`), "s_n", "lam_n",
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
    radius = c.bound(sol.lam)  # (N_t,) the friction radius at λ
    j = interface.jumps(model, sol, radius, lambda: c.W_n.min())
    Bu, th = j.Bu, j.th  # Bu: W_k·[u]_n, W_k·[u]_τ in B_full's row order
    jump_t = c.tangential(Bu) / c.W_t  # nodal tangential (mortar) jump
    nodes = c.tr.nodes[c.rows_t]
    u_s = j.x_full[c.slave.u_dofs(nodes)]  # (N_t, 2)
    ut_s = np.einsum("ij,ij->i", u_s, c.tr.tangents[c.rows_t])
    normal = np.full(c.tr.size, "touch", dtype=object)  # bilateral: every node touches
    if c.law == "unilateral":
        normal[c.rows_n] = node_states.normal_states(lam_n, (c.gap0 - c.normal(Bu)) / c.W_n, th)
    touch = normal[c.rows_n] == "touch"  # (N_n,)
    touch_t = normal[c.rows_t] == "touch"  # (N_t,)
    rho = radius * (normal[c.rows_t] != "open")  # (N_t,); an open node has no friction
    tang = node_states.tangential_states(lam_t, rho, c.tangential(j.Bi) / c.W_t, th)
    labels = node_states.node_states(normal[c.rows_t], tang)  # (N_t,)
    slip = labels == "slip"
    weights = rho * c.W_t  # (N_t,) ∫ρφ̃_k (bilateral: g_weights)
    g_abs = float(np.sum(weights * np.abs(c.tangential(j.Bi) / c.W_t)))
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
        state["u_n"] = c.normal(Bu) / c.W_n  # (N_n,) normal (mortar) jump [u]_n
        state["gap"] = c.gap0 / c.W_n  # (N_n,) initial gap
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


count = partial(contact_model.count, SCENE_MODEL)
update = partial(contact_model.update_scene, SCENE_MODEL)
incremental = contact_model.incremental


from .error_estimate import estimate as _estimate  # noqa: E402 (issue 32)

estimate = partial(_estimate, SCENE_MODEL)  # a posteriori error indicators per cell
