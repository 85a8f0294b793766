"""What the contact plug-in's fronts plane (2D) and solid (3D) share besides the contact law
(`contact_law`): the built model's bookkeeping (`BodiesModel`: the unknowns of each field, the
full vector with its Dirichlet values), the assembly of the bodies into the MixedVI
(`mixed_vi`), the nodal fields by name, the mesh size, and the check
of a BODY.BOUNDARY reference of a scene.

A body (`bodies.Body`, 2D or 3D) numbers its full dofs from `offset`:
displacement first (`u_dofs`), then potential on piezoelectric bodies; `split` cuts its part
of a full vector into displacement (N, d) and potential (N,) or None.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any

import numpy as np
import scipy.sparse as sp

from fem.dirichlet import expand, reduce_dirichlet
from problems.errors import SceneError
from problems.scene import Scene
from problems.scene.fields import load_parameter
from problems.scene.model import expressions, refuse
from vi_core import MixedVI, Solution, product
from vi_core.engine import row_partition

from ..contract import Sweep
from . import owned
from .bodies import build_body, dirichlet, field_data, gram, loads
from .interface import multiplier_rows
from .reports import interface_warnings


@dataclass
class BodiesModel:
    """A built contact scene: the mixed VI plus what post-processing needs (the plug-ins'
    `Model` subclasses add their own fields)."""

    scene: Scene
    level: int
    bodies: list[Any]
    contact: Any
    vi: MixedVI
    free: np.ndarray  # (n_free,) full indices of the unknowns
    values: np.ndarray  # (n_full,) prescribed values (fixed entries)
    options: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    rhs: Rhs | None = None  # f and gap from loads and values (load steps: `update`)
    # load paths (`incremental`): B_full x of the previous step on the tangential rows, 0 on
    # the normal ones; the friction law acts on B_full x − slip_origin (None: total form)
    slip_origin: np.ndarray | None = None

    def full_fields(self) -> dict[str, np.ndarray]:
        """Boolean masks over the full vector (prescribed entries included): which entries are
        displacement, which potential."""
        is_disp = np.zeros(self.values.size, dtype=bool)  # (n_full,)
        for b in self.bodies:
            is_disp[b.u_dofs(np.arange(b.n_nodes)).ravel()] = True
        return {"displacement": is_disp, "potential": ~is_disp}

    def unknown_fields(self) -> dict[str, np.ndarray]:
        """Boolean masks over the unknowns: which are displacement, which potential."""
        return {k: v[self.free] for k, v in self.full_fields().items()}

    @property
    def dofs(self) -> dict[str, int]:
        """Number of unknowns per field."""
        counts = {k: int(v.sum()) for k, v in self.unknown_fields().items()}
        return {**counts, "multiplier": self.vi.m}

    def full(self, u: np.ndarray) -> np.ndarray:
        """Unknowns → full vector including Dirichlet values."""
        return expand(u, self.free, self.values)


def build_bodies(spec: Any, level: int) -> dict[str, Any]:
    """The bodies of a validated scene model `spec` at `level` by name, their full dofs
    numbered one after the other (`bodies.build_body`)."""
    out: dict[str, Any] = {}
    offset = 0
    for name, section in spec.bodies.items():
        out[name] = build_body(name, section, level, offset)
        offset += out[name].size
    return out


def interface_references(bodies: dict[str, Any], contact: Any) -> str:
    """The slave body of a [contact] table (`reference` checks slave and master), refusing a
    master boundary on the slave body itself."""
    slave, _ = reference(bodies, ["contact", "slave"], contact.slave)
    if contact.master != "rigid":
        master, _ = reference(bodies, ["contact", "master"], contact.master)
        if master == slave:
            raise refuse(
                ["contact", "master"],
                contact.master,
                '"rigid" or BODY.BOUNDARY of a body other than the slave',
            )
    return slave


def built(build: Callable[[Scene, int | None], Any], scene: Scene, level: int | None) -> Any:
    """build(scene, level) with floating-point warnings silenced (the data are checked where
    they are read); a SceneError raised while building names the scene file."""
    try:
        with np.errstate(all="ignore"):
            return build(scene, level)
    except SceneError as err:
        raise (err if err.file else err.in_file(scene.path)) from None


def assemble(
    spec: Any,
    scene: Scene,
    level: int | None,
    interface: Callable[[dict[str, Any], Any, int, int], Any],
    model_class: type[BodiesModel],
    options: dict | None = None,
) -> Any:
    """The built `model_class` of a validated scene model `spec` (of `scene`) at `level` (None:
    the scene's), 2D and 3D alike: its bodies, the contact interface
    `interface(bodies by name, spec.contact, n_full, level)` of its [contact] table (None
    without one) and the mixed VI (`mixed_vi`, the data checked by `checks.finite_data`);
    `options` (the front's) come before the scene's solver options; the warnings start with
    the interface's (`reports.interface_warnings`)."""
    from .checks import finite_data

    level = spec.scene.level if level is None else level
    bodies = build_bodies(spec, level)
    n_full = sum(b.size for b in bodies.values())
    contact = None if spec.contact is None else interface(bodies, spec.contact, n_full, level)
    info = {"scene": scene.name, "level": level}
    check = partial(finite_data, contact=contact)
    vi, free, values, rhs = mixed_vi(list(bodies.values()), contact, info, check=check)
    options = {**(options or {}), **spec.options()}
    warnings = [] if contact is None else interface_warnings(contact)
    bodies_ = list(bodies.values())
    return model_class(scene, level, bodies_, contact, vi, free, values, options, warnings, rhs)


def mixed_vi(
    bodies: list[Any],
    contact: Any,
    info: dict,
    check: Callable | None = None,
) -> tuple[MixedVI, np.ndarray, np.ndarray, Rhs]:
    """The bodies' blocks side by side, reduced by their Dirichlet data, and the contact rows:
    (the MixedVI, free (n_free,) the full indices of the unknowns, values (n_full,) the
    prescribed values, the `Rhs` that recomputes f and gap from other loads and values).
    contact the front's contact (None: no multipliers), whose rows are
    `interface.multiplier_rows`; the MixedVI's `fields` and `near_null` are
    `bodies.field_data`'s; check(A_full, f_full, values) may refuse the assembled data (under
    an engine's row partition A_full is never whole: `owned.check` reads its three parts, every
    rank refusing alike, and vi holds its rows of A only: `owned.reduced`, `MixedVI.partition`).
    Each body's operator A is released (vi.A is the copy kept: memory; paper scene level 5:
    117 MB of bodies' A); a body keeps A's rows of its prescribed dofs, `A_fixed` (its
    reactions: `piezo_balance`). vi.X, the norm of `vi_core.constants`, is a function that
    assembles it when asked (held for the whole solve, it was 73 MB at level 5, and
    `constants` refuses sizes above 200,000 unknowns)."""
    partition = row_partition()
    if partition is None:
        A_full = sp.block_diag([b.A for b in bodies], format="csr")
        for b in bodies:
            b.A_fixed, b.A = b.A[np.flatnonzero(b.fixed)], None
    f_full = np.concatenate([b.f for b in bodies])
    fixed = np.concatenate([b.fixed for b in bodies])
    values = np.concatenate([b.values for b in bodies])
    dof = np.flatnonzero(fixed)  # (n_fixed,)
    if partition is None:
        if check is not None:
            check(A_full, f_full, values)
        A, _, free = reduce_dirichlet(A_full, f_full, fixed, values)
        A_fixed = A_full[free][:, dof].tocsr()  # (n_free, n_fixed)
    else:  # an engine's: each process assembles its owned rows only (`owned.reduced`)
        free = np.flatnonzero(~fixed)  # (n_free,)
        A, A_fixed, fixed_rows = owned.reduced(bodies, partition)
        at = np.searchsorted(dof, [b.offset for b in bodies] + [fixed.size])  # (bodies + 1,)
        for b, i, j in zip(bodies, at[:-1], at[1:], strict=True):
            b.A_fixed = fixed_rows[i:j][:, b.offset : b.offset + b.size]
        if check is not None:  # A's rows on their process only: refused alike on every one
            owned.check(check, partition, (A, A_fixed, fixed_rows), f_full, values)
        del fixed_rows
    if contact is None:
        B, Lam, Y = sp.csr_matrix((0, free.size)), product(), sp.csr_matrix((0, 0))
        rhs = Rhs(A_fixed, None, None, free, dof, fixed)
    else:
        B_full, gap0, Lam, Y = multiplier_rows(contact)
        B = B_full[:, free]
        rhs = Rhs(A_fixed, B_full[:, dof].tocsr(), gap0, free, dof, fixed)
    f, gap = rhs.at(f_full, values)
    vi = MixedVI(
        A=A,
        B=B,
        f=f,
        Lambda=Lam,
        gap=gap,
        X=partial(_gram, bodies, free),
        Y=Y,
        info=info,
        **field_data(bodies, free, values.size),  # for the iterative linear path
        partition=partition,  # an engine's: vi.A holds this process's rows only
    )
    return vi, free, values, rhs


def _gram(bodies: list[Any], free: np.ndarray) -> sp.csr_matrix:
    """(n_free, n_free) the bodies' H1 Gram matrices side by side on the unknowns."""
    return sp.csr_matrix(sp.block_diag([gram(b) for b in bodies], format="csr")[free][:, free])


@dataclass
class Rhs:
    """The right-hand side of a built model as a function of its loads and prescribed values
    (a load step: `update`): f = f_full[free] − A_full[free, fixed] values[fixed] and
    gap = gap0 − B_full[:, fixed] values[fixed], exactly as `reduce_dirichlet` and the contact
    rows compute them at build."""

    A_fixed: sp.csr_matrix  # (n_free, n_fixed) A_full's columns of the prescribed dofs
    B_fixed: sp.csr_matrix | None  # (m, n_fixed) B_full's columns of the prescribed dofs
    gap0: np.ndarray | None  # (m,) the gap rows not from Dirichlet data (initial gaps)
    free: np.ndarray  # (n_free,) full indices of the unknowns
    dof: np.ndarray  # (n_fixed,) full indices of the prescribed dofs
    fixed: np.ndarray  # (n_full,) bool: which dofs are prescribed

    def at(self, f_full: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(f (n_free,), gap (m,) or None) for loads f_full (n_full,) and values (n_full,)."""
        v = values[self.dof]  # (n_fixed,)
        f = f_full[self.free] - self.A_fixed @ v
        gap = None if self.B_fixed is None else self.gap0 - self.B_fixed @ v
        return f, gap


# where the load parameter t may appear for `update` (any other t-dependent value: rebuild)
UPDATABLE = re.compile(
    r"bodies\.[^.\[]+\.((displacement|traction|potential|charge)\[\d+\]\.value"
    r"|body_force|free_charge)(\[\d+\])?"
)


def update(model: BodiesModel, spec: Any, t: float) -> BodiesModel | None:
    """The load step t of a built model (the contract's `update`): a copy of `model` with the
    loads and prescribed values of the validated scene model `spec` at t, and the MixedVI's f
    and gap recomputed from them (`Rhs`); mesh, operators, contact rows and Λ are shared. None
    where the step needs a rebuild: t in any other value (a gap, a friction bound), an outer
    iteration that replaces model.vi (electrical contact), or data that are not finite (the
    rebuild refuses them with the field named)."""
    rhs = model.rhs
    if rhs is None or getattr(model, "electrical", None) is not None:
        return None
    if any(e.uses_t and not UPDATABLE.fullmatch(e.path) for e in expressions(spec)):
        return None
    with load_parameter(t):
        f_full = np.concatenate([loads(spec.bodies[b.name], b) for b in model.bodies])
        data = [dirichlet(spec.bodies[b.name], b) for b in model.bodies]
    fixed = np.concatenate([d[0] for d in data])
    values = np.concatenate([d[1] for d in data])
    finite = np.isfinite(f_full).all() and np.isfinite(values).all()
    if not (finite and np.array_equal(fixed, rhs.fixed)):
        return None
    f, gap = rhs.at(f_full, values)
    vi = model.vi.with_rhs(f=f, gap=gap)
    return replace(model, vi=vi, values=values, warnings=list(model.warnings), slip_origin=None)


def fields(model: BodiesModel, sol: Solution) -> dict[str, np.ndarray]:
    """Nodal fields by name: "BODY.displacement" (N, d) and, for piezoelectric bodies,
    "BODY.potential" (N,)."""
    x_full = model.full(sol.u)
    out = {}
    for b in model.bodies:
        u, phi = b.split(x_full[b.offset : b.offset + b.size])
        out[f"{b.name}.displacement"] = u
        if phi is not None:
            out[f"{b.name}.potential"] = phi
    return out


def mesh_size(model: BodiesModel) -> float:
    """h of the built level: the largest cell diameter over the bodies."""
    return max(b.mesh.h for b in model.bodies)


def reference(bodies: dict[str, Any], field_: list[str], ref: str) -> tuple[str, str]:
    """BODY.BOUNDARY → (body, boundary), checked against the scene's [bodies] tables and
    their geometries' boundary names (not checked for a geometry without fixed names: a mesh
    file, whose groups are checked when it is read)."""
    bname, dot, part = ref.partition(".")
    if not dot:
        raise refuse(field_, ref, "BODY.BOUNDARY, e.g. block.bottom")
    if bname not in bodies:
        raise refuse(field_, ref, f"BODY.BOUNDARY with a body of this scene: {', '.join(bodies)}")
    names = bodies[bname].geometry.BOUNDARIES
    if names is not None and part not in names:
        raise refuse(field_, ref, f"BODY.BOUNDARY with a boundary of {bname!r}: {', '.join(names)}")
    return bname, part


def update_scene(scene_model: type, model: BodiesModel, scene: Scene, t: float) -> Any:
    """Load paths (contract `update`, with the front's `scene_model` bound): the step t of
    `model` with only its loads and prescribed values re-read (`update`; None: rebuild the
    step, e.g. with [contact.electrical])."""
    return update(model, scene.validated(scene_model), t)


def count(scene_model: type, scene: Scene, levels: Sequence[int]) -> list[tuple[int, int, int]]:
    """(unknowns n + m, stored entries of A, n) of each of `levels` (contract `count`, with the
    front's `scene_model` bound), counted on the level-0 meshes without building them
    (`sizes.sizes`); its errors name the scene file, as the build's do."""
    from .sizes import sizes

    return built(lambda s, _: sizes(s.validated(scene_model), levels), scene, None)


def incremental(model: Any, previous: Any, previous_sol: Solution) -> None:
    """Load paths: the friction law of the next step `model` acts on the slip since the
    previous step, [u]_t − [u_prev]_t: the tangential rows of the gap are shifted by
    B_t x_prev (x_prev the previous step's full solution, Dirichlet values included), so that
    B_t u − gap_t = B_t (x − x_prev). The normal rows (`contact.idx_n`) keep the total
    displacement. 2D and 3D alike."""
    c = model.contact
    if c is None:
        return
    origin = c.B_full @ previous.full(previous_sol.u)  # (m,) in B_full's row order
    origin[c.idx_n] = 0.0
    model.slip_origin = origin
    model.vi = model.vi.with_rhs(gap=model.vi.gap + origin)


def friction_sweep(g_file: str, F_file: str) -> Sweep:
    """The contract's SWEEP of a front: the friction bound g (Tresca) or else the coefficient
    F (Coulomb) at 1.5, 1 and 0.6 times the scene's, drawn into `g_file` or `F_file`."""
    return Sweep(
        "contact.g",
        "friction bound g [Pa]",
        factors=(1.5, 1.0, 0.6),
        file=g_file,
        otherwise=Sweep(
            "contact.F", "friction coefficient F [1]", factors=(1.5, 1.0, 0.6), file=F_file
        ),
    )
