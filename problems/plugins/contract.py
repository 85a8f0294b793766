"""The plug-in contract (version CONTRACT = 2): what `mixvi` expects from a problem module and
from the model it builds.

Contract version CONTRACT = 2. A plug-in is one module (or any object) with

    CONTRACT: int = 2                          the contract version it is written against
                                               (checked at registration: 1 or missing → refused
                                               with the list of what changed, docs/plugins.md)
    NAME: str                                  the name scenes use: [scene] plugin = NAME
    DESCRIPTION: str                           one line for listings
    SCENE_MODEL: type[SceneModel]              its scene model (pydantic): every key, type,
                                               range and cross-reference of its scenes
    build(scene, level) -> Model               validated scene → assembled mixed VI
    postprocess(model, sol, outdir) -> dict    solution → files in outdir + summary entries

and, optionally, what the other commands need (a command refuses a plug-in without the
declaration it needs with exit status 2, naming the declaration):

    SWEEP: Sweep                               `mixvi figures`: the scene parameter swept, its
                                               values (absolute or factors of the scene's value),
                                               its label with units, the figure's file name
    draw(ax, model, sol) -> str                `mixvi figures`: one panel of the sweep, returns
                                               the panel's note (default: `draw_multiplier`,
                                               the multiplier and slack per constraint row)
    NORMS: tuple[str, ...]                     `mixvi study`: names of the error norms, in the
                                               order they are printed (the first ones fitted)
    mesh_size(model) -> float                  `mixvi study`: h of the built level
    exact_errors(model, sol) -> dict | None    `mixvi study`: the NORMS against the scene's exact
                                               solution (None: the scene has none)
    EXACT_NORMS: tuple[str, ...]               `mixvi study`: the names of exact_errors' norms
                                               where they differ from NORMS (default NORMS)
    reference_errors(model, sol, ref, ref_sol) `mixvi study`: the NORMS against the solution of a
                         -> dict               finer level `ref` of the same scene
    extremes() -> list[ExtremeRow]             `mixvi extremes`: this plug-in's extreme rows
    warm_start(coarse, coarse_sol, fine)       `mixvi solve`, `bench`: nested iteration's
                         -> dict               initial guess: keyword arguments of solve
                                               (lam0, u0), and optionally "start", a dict
                                               saying how they were obtained, which goes to
                                               solver_info["nested_start"] (`nested_start`)
    count(scene, levels) -> [(unknowns, nnz, n)]  level caps and memory estimates: the sizes
                                               of levels without building them (else built)
    DIMENSION: int                             with count: the models' `dimension`, so that
                                               the estimate builds no level at all
    solve(model, **options) -> Solution       `mixvi solve`, the Python API, the regression
                                               baselines: an outer iteration around model.vi
                                               (e.g. the contact plug-in's electrical fixed
                                               point); default vi_core.solve(model.vi, **options)
                                               (`solve_model`, re-exported by
                                               problems.pipeline: every command solves
                                               through it)
    problem_at(model, sol) -> MixedVI          with `solve`: the mixed VI the answer `sol`
                                               must solve (e.g. the VI with the electrical
                                               conductances frozen at k(λ_n) of `sol`),
                                               which `mixvi check` and `extremes` judge it
                                               against; default model.vi
                                               (`problem_at`)
    incremental(model, previous, previous_sol) load paths (`[load_path]`, mixvi solve and
                         -> None               `problems.solve_scene`): make `model`, the next
                                               load step just built, act on the increments
                                               since `previous` (the step before, solved as
                                               `previous_sol`) before it is solved — e.g. a
                                               friction law on the slip increment: shift the
                                               tangential gap by B_t x_prev (replace model.vi
                                               by model.vi.with_rhs(gap=...)). Without it
                                               every step is solved in total form (path-
                                               independent; the summary says so)
    update(model, scene, t) -> Model | None    load paths: the next load step t from the
                                               previous step's model, re-reading only what
                                               depends on t (loads, prescribed displacements
                                               and potentials) and sharing mesh and operators
                                               (called inside `load_parameter(t)`; must not
                                               change `model`); None: that step is built.
                                               Without it every step is built from the scene
                                               (the answers are the same to rounding)
    estimate(model, sol) -> dict[str, Indicator]  `mixvi solve` (estimate_BODY.vtu, summary
                                               "estimate"; `--accuracy`): per body its mesh,
                                               the (n_cells,) a posteriori indicators η_T and
                                               the energy ‖U_h‖² the relative estimate
                                               divides by (`Indicator`)
    step_output(model, sol, outdir) -> dict    load paths: the files of one load step (cheap:
                                               VTU datasets, tables; no plots) and the summary
                                               entries "files" and "contact" (counts per state:
                                               stick, slip, open); default: postprocess

and the `Model` it returns carries

    vi: MixedVI                                the discrete problem A u + Bᵀλ = f, λ ∈ Λ, ...
    level: int                                 the refinement level actually built
    dofs: dict[str, int]                       unknowns per field (printed and summarised)
    options: dict                              e.g. {"method": "ssn", "tol": 1e-10} from the scene
    warnings: list[str]                        anything the user should read

and optionally
    dimension: int                             the geometry's dimension (default 2): each
                                               level multiplies the unknowns by 2**dimension
                                               in the memory estimate before a level is built
    errors(sol) -> dict[str, float]            errors against a known exact solution
                                               (e.g. {"h1": ..., "l2": ...}, plus "h")
    complementarity(sol) -> float              relative defect of a Lemma-4.2-type identity
                                               λᵀ(Bu − gap) = (support function term), 0 exactly

`mixvi solve` calls exactly: build → `vi_core.solve(model.vi, method=options.get("method",
"ssn"), tol=options.get("tol", 1e-10))` (or the plug-in's `solve`) →
postprocess, and merges the returned dict into summary.json; the keys "contact" ({"nodes",
"stick", "slip"}, optionally
"mortar_patch_defect": above 1e-8 `mixvi solve` exits 1 unless --allow-defect) and "lemma_4_2"
(a float) are also printed. Before anything is built the scene is validated by SCENE_MODEL
(`mixvi validate`, `mixvi schema` shows the JSON Schema); `build` reads the scene only through
`scene.validated(SCENE_MODEL)` (cached) and raises `SceneError(field, value, allowed)` for
what only the built mesh can tell (an expression's value, a mesh too large), naming the field
with the sections' `key(name)` and the expressions' own `path`.

Optionally a plug-in also provides `fields(model, sol) -> dict[str, np.ndarray]` (nodal fields
by name) and `contact_state(model, sol) -> dict` for the Python API (`problems.solve_scene`).

The helpers below are shared by the built-in scalar plug-ins and are free to use in your own.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Protocol, runtime_checkable

import numpy as np
from pydantic import BeforeValidator, Field

import vi_core
from fem.mesh import Mesh
from problems.errors import SceneError
from problems.scene import Scene, SceneModel, Section, load_scene
from problems.scene.fields import Expression, Text, Vector, evaluate
from problems.scene.model import refuse
from vi_core import MixedVI, Solution


@runtime_checkable
class Model(Protocol):
    """What `build` returns (a dataclass in the built-in plug-ins)."""

    vi: MixedVI
    level: int
    options: dict
    warnings: list[str]

    @property
    def dofs(self) -> dict[str, int]:
        """Number of unknowns per field, e.g. {"displacement": 130, "multiplier": 17}."""


@runtime_checkable
class Plugin(Protocol):
    """A problem module: `registry` accepts any object with these five attributes."""

    NAME: str
    DESCRIPTION: str
    SCENE_MODEL: type[SceneModel]

    def build(self, scene: Scene, level: int | None) -> Model:
        """Scene → Model; `level` None means the scene's default level."""

    def postprocess(self, model: Model, sol: Solution, outdir: Path) -> dict:
        """Write result files into `outdir` and return summary entries (JSON-able)."""


CONTRACT = 2
"""The contract version this mixvi implements; a plug-in declares the one it is written for."""

V1_TO_V2 = (
    "declare CONTRACT = 2 and SCENE_MODEL, the scene model read by build through "
    "scene.validated(SCENE_MODEL) (Scene.root() and Table are gone); optionally SWEEP "
    "(mixvi figures), NORMS, mesh_size, exact_errors, "
    "reference_errors (mixvi study), extremes() (mixvi extremes) — see docs/plugins.md, "
    "'From contract v1 to v2'"
)


@dataclass(frozen=True, eq=False)
class Indicator:
    """One body's a posteriori error indicators (the optional `estimate` declaration)."""

    mesh: Mesh
    eta: np.ndarray  # (n_cells,) η_T ≥ 0, the estimate is (Σ η_T²)^{1/2}
    energy: float  # ‖U_h‖² in the norm η estimates (relative estimate: η / √energy)
    # boundary part → projection of points (k, 2) onto its true curve (the geometry's
    # `curves`): where a refinement of `mesh` puts its new boundary nodes
    curves: Mapping[str, Callable[[np.ndarray], np.ndarray]] = field(default_factory=dict)


@dataclass(frozen=True)
class Sweep:
    """What `mixvi figures` sweeps: the scene value at `path` (dotted, as for --set) set to each
    of `values`, or to the scene's own value times each of `factors` (exactly one is given);
    `label` names the parameter with its units, e.g. "friction bound g [Pa]". `otherwise`: the
    sweep for a scene without a number at `path` (Coulomb friction has a coefficient F where
    Tresca friction has a bound g)."""

    path: str
    label: str
    values: tuple[float, ...] = ()
    factors: tuple[float, ...] = ()
    file: str = "sweep.png"
    otherwise: Sweep | None = None

    def __post_init__(self) -> None:
        if bool(self.values) == bool(self.factors):
            raise ValueError(f"Sweep({self.path!r}): give exactly one of values and factors")


Checks = Callable[[Any, "ExtremeRow", Any, Solution], tuple[dict, list[str]]]
"""check(plugin, row, model, sol) -> (record entries, notes) of one extreme row."""


@dataclass
class ExtremeRow:
    """One row of `mixvi extremes`: a scene pushed to extreme data, and what is checked.

    The scene is the shipped one named `scene` with the `--set`-style `overrides` (and `edit`,
    a direct change of the raw scene data where an override cannot delete a key), built at
    `level`. Every row gets the generic checks of `mixvi extremes` (ssn's residual, agreement
    with the conic and homotopy answers, λ ∈ Λ, the model's complementarity identity); each of
    `checks` (`check(plugin, row, model, sol)`) adds record entries and notes (a note starting
    with "FAIL" fails the row). `huge` rows run only with --huge.
    """

    name: str
    scene: str
    overrides: Sequence[str] = ()
    level: int = 1
    edit: Callable[[dict], None] | None = None
    checks: Sequence[Checks] = ()
    huge: bool = False
    plugin: str = field(default="", compare=False)  # filled in by `mixvi extremes`

    def load(self, extra: Sequence[str] = ()) -> Scene:
        """The row's scene: the shipped one with the overrides (then `extra`) and the edit."""
        scene = load_scene(self.scene, [*self.overrides, *extra])
        if self.edit is not None:
            self.edit(scene.data)
        return scene


def expect(counts: Callable[[Any, Solution], dict[str, int]], **want: int | str) -> Checks:
    """An extreme-row check: the counts of `counts(model, sol)` recorded, and each named one
    held to `want` (an int: exactly that; "> 0": at least one); a miss fails the row."""

    def check(plugin: Any, row: ExtremeRow, model: Any, sol: Solution):
        rec = counts(model, sol)
        notes = [", ".join(f"{k} {v}" for k, v in rec.items())]
        for k, w in want.items():
            ok = rec[k] > 0 if w == "> 0" else rec[k] == w
            if not ok:
                notes.append(f"FAIL: {k} = {rec[k]}, expected {w}")
        return rec, notes

    return check


def conforms(obj: Any) -> list[str]:
    """What `obj` lacks to be a plug-in of this contract version (empty list: it conforms)."""
    missing = []
    version = getattr(obj, "CONTRACT", 1)
    if version != CONTRACT:
        missing.append(
            f"CONTRACT = {CONTRACT} (it declares contract version {version!r}; from v1: {V1_TO_V2})"
        )
    for attr, kind in (("NAME", str), ("DESCRIPTION", str)):
        if not isinstance(getattr(obj, attr, None), kind):
            missing.append(f"{attr} (a string)")
    for attr in ("build", "postprocess"):
        if not callable(getattr(obj, attr, None)):
            missing.append(f"{attr}() (a function)")
    sm = getattr(obj, "SCENE_MODEL", None)
    if not (isinstance(sm, type) and issubclass(sm, SceneModel)):
        missing.append("SCENE_MODEL (a subclass of problems.scene.SceneModel; contract 2)")
    optional = (
        "draw",
        "mesh_size",
        "exact_errors",
        "reference_errors",
        "extremes",
        "warm_start",
        "count",
        "solve",
        "problem_at",
        "incremental",
        "step_output",
        "estimate",
    )
    for attr in optional:
        if hasattr(obj, attr) and not callable(getattr(obj, attr)):
            missing.append(f"{attr}() (a function, when declared)")
    if hasattr(obj, "SWEEP") and not isinstance(obj.SWEEP, Sweep):
        missing.append("SWEEP (a problems.plugins.contract.Sweep, when declared)")
    norms = getattr(obj, "NORMS", ())
    if not (isinstance(norms, tuple) and all(isinstance(k, str) for k in norms)):
        missing.append("NORMS (a tuple of names, when declared)")
    return missing


def solve_model(plugin: Any, model: Any, **options: Any) -> Solution:
    """The plug-in's `solve(model, **options)` if it has one (an outer iteration around the
    VI), else `vi_core.solve(model.vi, **options)`."""
    if hasattr(plugin, "solve"):
        return plugin.solve(model, **options)
    return vi_core.solve(model.vi, **options)


def nested_start(plugin: Any, coarse: Any, coarse_sol: Solution, fine: Any) -> tuple[dict, dict]:
    """Nested iteration's start of `fine` from the solved `coarse` level (the plug-in's
    `warm_start`): the keyword arguments of `solve_model`, and what the start carries, for
    solver_info["nested_start"]: the coarse level, the arguments given ("lam0": the
    multipliers, "u0": the primal unknowns; without "u0" the first Newton step starts from
    u = 0) and the plug-in's "start" entry."""
    kw = dict(plugin.warm_start(coarse, coarse_sol, fine))
    start = {"from_level": coarse.level, "carries": sorted(k for k in kw if k != "start")}
    start.update(kw.pop("start", {}))
    return kw, start


def problem_at(plugin: Any, model: Any, sol: Solution) -> MixedVI:
    """The mixed VI that `sol` must solve: the plug-in's `problem_at(model, sol)` where its
    `solve` iterates around the VI (the contact plug-in's electrical contact: the VI with the
    conductances frozen at k(λ_n) of `sol`), else `model.vi`. Checkers judge an answer of
    `solve_model` against this problem, never against the VI the solver was last given."""
    if hasattr(plugin, "problem_at"):
        return plugin.problem_at(model, sol)
    return model.vi


def draw_multiplier(ax, model: Any, sol: Solution) -> str:
    """The default panel of `mixvi figures` for a plug-in without `draw`: the multiplier λ and
    the constraint slack Bu − gap against the constraint row (any mixed VI has both)."""
    rows = np.arange(model.vi.m)  # (m,)
    ax.plot(rows, sol.lam, "o-", ms=2, label=r"$\lambda$")
    ax.set_xlabel("constraint row")
    ax.set_ylabel(r"multiplier $\lambda$")
    ax2 = ax.twinx()
    slack = model.vi.B @ sol.u - model.vi.gap  # (m,)
    ax2.plot(rows, slack, "s-", ms=2, color="tab:orange", label="Bu − gap")
    ax2.set_ylabel("slack Bu − gap", color="tab:orange")
    ax.legend(loc="best", fontsize=8)
    return f"|λ|max {float(np.abs(sol.lam).max(initial=0.0)):.3g}"


def needs(plugin: Any, option: str, *attrs: str) -> None:
    """SceneError (exit 2) naming what `plugin` does not declare for the command `option`."""
    lacking = [a for a in attrs if not hasattr(plugin, a)]
    if lacking:
        raise SceneError(
            "scene.plugin",
            plugin.NAME,
            f"a plug-in declaring {', '.join(lacking)} ({option} needs it; contract "
            f"v{CONTRACT}, docs/plugins.md)",
        )


# ------------------------------------------------------------------ helpers for plug-ins
Boundaries = Annotated[
    list[Text],
    BeforeValidator(
        lambda v: [v] if isinstance(v, str) else v, json_schema_input_type=str | list[str]
    ),
    Field(min_length=1),
]


def check_boundaries(field: list, names: list[str], available) -> None:
    """Refuse (a pydantic error at `field`) any of `names` not among `available` (a geometry's
    BOUNDARIES; None: known only once meshed, checked then)."""
    if available is None:
        return
    for n in names:
        if n not in available:
            raise refuse(field, n, f"a boundary of this geometry: {', '.join(available)}")


def prescribed_once(key: str, parts: Sequence[tuple[Sequence[str], str]]) -> None:
    """Refuse (a pydantic error at `key`[i].boundary) two entries of one list of Dirichlet
    data that prescribe the same component on the same boundary part: which value would hold
    is not the scene's to leave open (the later entry used to win silently), even where they
    agree. `parts`: per entry, its boundary names and its components (e.g. "xy"; "" for a
    scalar). Parts that only meet at a corner node are not refused."""
    seen: dict[tuple[str, str], int] = {}
    for i, (names, components) in enumerate(parts):
        for name in names:
            for c in components or "-":
                if (name, c) in seen:
                    what = f" component {c} of" if components else ""
                    raise refuse(
                        [key, i, "boundary"],
                        name,
                        f"a boundary part prescribed once: {key}[{seen[name, c]}] already "
                        f"prescribes{what} {name!r} (merge the two entries, or name another part)",
                    )
                seen[name, c] = i


def check_meshed(mesh: Mesh, refs: Sequence[tuple[str, str]]) -> None:
    """After meshing a geometry whose BOUNDARIES are None (a mesh file): SceneError naming the
    field for the first (field path, boundary name) of `refs` the mesh does not have, listing
    the ones it has."""
    for key, name in refs:
        if name not in mesh.boundaries:
            have = ", ".join(sorted(mesh.boundaries)) or "(none)"
            raise SceneError(key, name, f"a boundary group of this mesh: {have}")


class ScalarExact(Section):
    """The optional [exact] table of a scalar plug-in: u and grad = [∂x u, ∂y u]."""

    source: Text = ""  # where the exact solution comes from (documentation only)
    u: Expression
    grad: Vector

    def compiled(self) -> tuple[Callable, Grad]:
        """(u(x, y), grad(x, y) → x.shape + (2,))."""
        g = self.grad
        return self.u, lambda x, y: evaluate(g, x, y)


class DirichletPart(Section):
    """One [[dirichlet]] table of a scalar plug-in: boundary part(s) and the value there."""

    boundary: Boundaries
    value: Expression


def dirichlet(parts: list[DirichletPart], mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Scalar Dirichlet data: fixed (n_nodes,) bool and values (n_nodes,) (0 where free)."""
    fixed = np.zeros(mesh.n_nodes, dtype=bool)
    values = np.zeros(mesh.n_nodes)
    for t in parts:
        nodes = np.unique(np.concatenate([mesh.boundaries[p] for p in t.boundary]))  # (k,)
        fixed[nodes] = True
        values[nodes] = t.value(mesh.points[nodes, 0], mesh.points[nodes, 1])
    return fixed, values


Grad = Callable[[np.ndarray, np.ndarray], np.ndarray]


def complementarity_defect(lam: np.ndarray, slack: np.ndarray, support: float) -> float:
    """Relative defect of λᵀ(Bu − gap) = σ (σ = Σ g_i D_i |(Bu)_i| for Tresca rows, 0 else).

    slack = Bu − gap. Relative to max(|σ|, ‖λ‖‖slack‖): the Cauchy–Schwarz bound of the left
    side, so a pure complementarity (σ = 0) is measured as the cosine between λ and the slack.
    """
    lhs = float(lam @ slack)
    scale = max(abs(support), float(np.linalg.norm(lam) * np.linalg.norm(slack)), 1e-300)
    return abs(lhs - support) / scale


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """‖a − b‖ / ‖b‖ (a zero b: the absolute difference over 1e-300)."""
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def triangles(cells: np.ndarray) -> np.ndarray:
    """(n_tri, 3) triangles of the triangles or quadrilaterals `cells` (n, 3 or 4) for
    plotting (each quad split along a diagonal)."""
    if cells.shape[1] == 3:
        return cells
    return np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 2, 3]]])
