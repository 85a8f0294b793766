"""One battery for every plug-in: each shipped scene is solved by every applicable method, each
RAW answer is judged by the independent checker (vi_core.kkt: residual and complementarity),
the answers agree within what their residuals allow, errors converge at the rates the README
states (within 0.1, in the norm it names) against exact or manufactured solutions, the linear
limits match separate linear solves, and `mixvi solve` works.

No assertion restates what a solver imposed (e.g. |λ·τ| = g on nodes classified as slip, or an
identity computed from the assembled B and bounds that r2 = 0 implies). A skip says why.
A new plug-in is checked by adding its scene (and a small level) to SCENES.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import vi_core
from problems.commands import main as cli
from problems.commands.check import CONIC_RAW_ACCEPT
from problems.plugins import registry
from problems.plugins.contact import balance as piezo_balance
from problems.plugins.contact import plane as pc
from problems.plugins.contract import conforms
from problems.scene import load_scene
from problems.scene.exact import split_exact
from problems.scene.materials import NAMED
from vi_core.kkt import Checker

from .contact import checks

SCENES = [  # (scene, level)
    ("obstacle", 1),
    ("antiplane", 1),
    ("antiplane_manufactured", 1),
    ("signorini", 1),
    ("rigid_foundation", 0),
    ("manufactured", 1),
    ("paper_two_body", 0),
    ("curved_manufactured", 0),
]
TOL = 1e-10
ITERATE_ACCEPT = 10 * TOL  # ssn and homotopy iterate to TOL (same rule as `mixvi check`)
# the checker's complementarity defect; largest measured over SCENES: 5e-16, 1e-16, 6e-11
COMPLEMENTARITY = {"ssn": 1e-12, "homotopy": 1e-10, "conic": 1e-9, "fixed_point": 1e-10}


def _solve_all(vi):
    """Raw answers: ssn; homotopy unless A is symmetric (then it is one ssn call); conic
    without polishing unless A is general. A quasi-variational Λ (unilateral contact with
    contact-only Tresca or Coulomb friction): ssn and the fixed point on Tresca problems, each
    solved by conic (homotopy for a general A), as `mixvi check` does."""
    if vi.Lambda.quasi:
        inner = "conic" if vi.structure != "general" else "homotopy"
        return {
            m: vi_core.solve(vi, method=m, tol=TOL, **o)
            for m, o in (("ssn", {}), ("fixed_point", {"inner": inner}))
        }
    methods = {"ssn": {}}
    if vi.structure != "symmetric":
        methods["homotopy"] = {"report_constants": False}
    if vi.structure != "general":
        methods["conic"] = {"polish": 0}
    return {m: vi_core.solve(vi, method=m, tol=TOL, **o) for m, o in methods.items()}


@pytest.fixture(scope="module", params=SCENES, ids=[s for s, _ in SCENES])
def solved(request):
    name, level = request.param
    scene = load_scene(name)
    if name in ("manufactured", "curved_manufactured"):
        scene, _ = split_exact(scene)
    plugin = registry.for_scene(scene)
    model = plugin.build(scene, level)
    return scene, plugin, model, _solve_all(model.vi)


def test_builtins_conform():
    for name, mod in registry.plugins().items():
        assert conforms(mod) == [], name
        assert mod.NAME == name


def test_model_contract(solved):
    _, _, model, _ = solved
    assert isinstance(model.vi, vi_core.MixedVI)
    assert isinstance(model.level, int) and isinstance(model.warnings, list)
    assert all(isinstance(v, int) for v in model.dofs.values())
    assert sum(model.dofs.values()) == model.vi.n + model.vi.m


def test_every_raw_answer_passes_the_independent_checker(solved):
    _, _, model, sols = solved
    check = Checker.of(model.vi)
    for meth, sol in sols.items():
        k = check(sol.u, sol.lam)
        need = CONIC_RAW_ACCEPT if meth == "conic" else ITERATE_ACCEPT
        assert k.relative <= need, (meth, k)
        if meth != "conic":
            assert sol.converged, meth


def test_complementarity_from_the_independent_checker(solved):
    """λᵀ(Bu − gap) = σ_Λ(Bu − gap) and λ ∈ Λ, computed by vi_core.kkt for every plug-in."""
    _, _, model, sols = solved
    check = Checker.of(model.vi)
    for meth, sol in sols.items():
        k = check(sol.u, sol.lam)
        assert k.complementarity <= COMPLEMENTARITY[meth], (meth, k.complementarity)
        assert k.feasibility <= 1e-9, (meth, k.feasibility)


def test_raw_answers_agree_within_allowed(solved):
    """Pairs differ (raw answers, not a polished copy) and by no more than `allowed`."""
    _, _, model, sols = solved
    check = Checker.of(model.vi)
    kappa = check.inverse_norm(sols["ssn"].u, sols["ssn"].lam)
    names = list(sols)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            c = check.compare((sols[b].u, sols[b].lam), (sols[a].u, sols[a].lam), kappa)
            assert max(c["diff_u"], c["diff_lam"]) <= c["allowed"], (a, b, c)
            assert max(c["diff_u"], c["diff_lam"]) > 0, (a, b)


PIEZO = ["rigid_foundation", "manufactured", "paper_two_body", "curved_manufactured"]


@pytest.mark.parametrize("name", PIEZO)
def test_piezo_physics_from_independent_code(name):
    """Force balance of every body and (rigid foundation) Lemma 4.2 by quadrature."""
    model, sol = checks.solved(name, 1)
    assert piezo_balance.force_balance(model, sol)["imbalance"] <= checks.BALANCE_OK
    lemma = piezo_balance.lemma_4_2(model, sol)
    if lemma is not None:
        assert lemma["gap"] <= 1e-8  # the quadrature of a non-polynomial g (manufactured)


def test_cli_solve(solved, tmp_path):
    scene, plugin, model, _ = solved
    if scene.name in ("manufactured", "curved_manufactured"):
        pytest.skip(f"{scene.name}: its [exact] table is read by `mixvi study`, not `solve`")
    out = tmp_path / "out"
    assert cli.main(["solve", scene.name, "--level", str(model.level), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] and summary["plugin"] == plugin.NAME
    assert any(f.endswith(".vtu") for f in summary["files"])
    assert any(f.endswith(".png") for f in summary["files"])
    for f in summary["files"]:
        assert (out / f).is_file(), f


# ------------------------------------------------------------------ refinement against exact
def _scalar_rate(name: str, levels: list[int]) -> float:
    scene = load_scene(name)
    plugin = registry.for_scene(scene)
    h, e = [], []
    for level in levels:
        model = plugin.build(scene, level)
        err = model.errors(vi_core.solve(model.vi, "ssn", tol=1e-12))
        h.append(err["h"])
        e.append(err["h1"])
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


REFINEMENT = [  # (scene, README's claim {norm: rate}, how it is measured)
    ("obstacle", {"h1": 0.98}, lambda: {"h1": _scalar_rate("obstacle", [1, 2, 3])}),
    (
        "antiplane_manufactured",
        {"h1": 1.00},
        lambda: {"h1": _scalar_rate("antiplane_manufactured", [2, 3, 4])},
    ),
    ("manufactured", checks.MANUFACTURED_RATES, checks.manufactured_rates),
    ("curved_manufactured", checks.CURVED_RATES, checks.curved_rates),
    ("signorini", None, None),
]


@pytest.mark.parametrize(("name", "claimed", "measure"), REFINEMENT, ids=[r[0] for r in REFINEMENT])
def test_refinement_rates(name, claimed, measure):
    """Observed rate = least-squares slope of log(error) against log(h) over the README's
    levels, within 0.1 of the README's rate in the README's norm."""
    if claimed is None:
        pytest.skip(f"{name}: no exact or manufactured solution yet (README says so)")
    rates = measure()
    assert checks.rates_off(rates, claimed) == {}, (rates, claimed)


# ------------------------------------------------------------------ linear limits
def _kkt_solve(vi, rows) -> np.ndarray:
    """u of the linear saddle point A u + B[rows]ᵀμ = f, B[rows] u = gap[rows] (SuperLU on the
    Jacobi-scaled system; no vi_core solver involved)."""
    d = 1.0 / np.sqrt(vi.A.diagonal())
    S = sp.diags(d)
    B = vi.B[rows] @ S
    r = 1.0 / np.sqrt(np.asarray(B.multiply(B).sum(axis=1)).ravel())
    B = sp.diags(r) @ B
    K = sp.bmat([[S @ vi.A @ S, B.T], [B, None]], format="csc")
    x = spla.spsolve(K, np.concatenate([d * vi.f, r * vi.gap[rows]]))
    return d * x[: vi.n]


def _rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def _piezo(overrides, level=1, edit=None):
    scene = load_scene("rigid_foundation", overrides)
    if edit is not None:
        edit(scene.data)
    model = pc.build(scene, level)
    return model, vi_core.solve(model.vi, "ssn", tol=1e-12)


def test_linear_limit_g_huge_is_tied():
    model, sol = _piezo(["contact.g=1e14"])
    assert _rel(sol.u, _kkt_solve(model.vi, np.arange(model.vi.m))) <= 1e-10


def test_linear_limit_g_zero_is_free_slip():
    model, sol = _piezo(["contact.g=0.0"])
    N = model.contact.tr.size
    assert _rel(sol.u, _kkt_solve(model.vi, np.arange(N))) <= 1e-10


def test_linear_limit_e_zero_is_decoupled():
    """coupling_scale = 0: u is the answer of the same scene with a purely elastic body, and φ
    the solution of the separate linear problem P φ = f_φ (its own Dirichlet data)."""
    bt = NAMED["BaTiO3"]

    def uncoupled(data):
        e0 = np.zeros((2, 3)).tolist()
        mat = {"kind": "piezoelectric", "C": bt["C"], "e": e0, "kappa": bt["kappa"]}
        data["bodies"]["block"]["material"] = mat

    def elastic(data):
        b = data["bodies"]["block"]
        b["material"] = {"kind": "anisotropic", "C": bt["C"]}
        b.pop("potential", None)
        data.pop("output", None)

    electrode = "bodies.block.potential=[{boundary='top', value='100*x'}]"  # φ ≠ 0
    coupled, sol = _piezo([electrode], edit=uncoupled)
    plain, psol = _piezo([], edit=elastic)
    fields = coupled.unknown_fields()
    u_c = sol.u[fields["displacement"]]
    assert _rel(u_c, psol.u) <= 1e-10
    pot = fields["potential"]
    A = coupled.vi.A.tocsr()
    P = A[pot][:, pot]
    assert abs(A[pot][:, ~pot]).max() == 0.0  # decoupled blocks
    phi = spla.spsolve(P.tocsc(), coupled.vi.f[pot])
    assert _rel(sol.u[pot], phi) <= 1e-10


def test_linear_limits_antiplane():
    """g huge: w = 0 on Γ3 (a Dirichlet problem); g = 0: no friction (a Neumann problem)."""
    scene = load_scene("antiplane", ["friction.g=1e12"])
    model = registry.for_scene(scene).build(scene, 1)
    sol = vi_core.solve(model.vi, "ssn", tol=1e-12)
    assert _rel(sol.u, _kkt_solve(model.vi, np.arange(model.vi.m))) <= 1e-10
    scene = load_scene("antiplane", ["friction.g=0.0"])
    model = registry.for_scene(scene).build(scene, 1)
    sol = vi_core.solve(model.vi, "ssn", tol=1e-12)
    free = spla.spsolve(model.vi.A.tocsc(), model.vi.f)
    assert _rel(sol.u, free) <= 1e-10
