"""`mixvi check`: solve with every applicable method and compare their RAW answers.

For a quasi-variational Λ (unilateral contact with Coulomb or contact-only Tresca friction)
the methods are ssn on the combined map and the fixed point on Tresca problems
(`vi_core.tresca_fixed_point`), whose Tresca problems are solved by conic (homotopy for a
general A); conic and homotopy do not apply directly.

Each method's own answer is compared, never a polished one: ssn as it stops, homotopy its last
fixed-point iterate, conic as Clarabel returns it (`polish=0`). Homotopy is run only when A is
not symmetric (for a symmetric A it is one call of its level-0 oracle, ssn: not an independent
answer). Every answer is judged by the independent checker `vi_core.kkt` (its own
equilibration, projection and residual; nothing shared with the solvers but the assembled
blocks). Polishing the conic answer by Newton steps is reported on a separate, labelled line
and never compared.

A record fails (exit status 1) when
- a method fails by its own criterion (ssn/homotopy: residual ≤ tol not reached; conic: Clarabel
  status not "optimal"), or its independent residual exceeds what it must reach: 10·tol for
  ssn and homotopy (which iterate to tol), CONIC_RAW_ACCEPT for Clarabel's raw answer; or
- a pair's contact states disagree at some node (plug-ins with `contact_state`: each answer's
  states by `vi_core.states` at its own residual, compared per node by
  `vi_core.states.compare` — a node ambiguous in either answer is no disagreement, touch/open
  or stick/slip contradictions are); or
- a pair differs by more than `allowed` (`vi_core.kkt.Checker.compare`):
      allowed = 10 · κ · (‖F(a)‖ + ‖F(b)‖) / min(‖u'‖, ‖λ'‖),
  κ = est‖J⁻¹‖₁ of the natural map's generalised Jacobian at the answer with the smallest
  independent residual, F the natural map, all in equilibrated variables, and the differences
  diff_u = ‖u'_a − u'_b‖/‖u'_b‖, diff_lam = ‖λ'_a − λ'_b‖/‖λ'_b‖ in the same variables.
"""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

import problems.pipeline as pipeline
import vi_core
from problems.errors import SceneError
from problems.output import signals
from problems.output.files import Output, claim
from problems.output.jsonable import jsonable
from vi_core import states as node_states
from vi_core.kkt import Checker

from . import options, resources
from .solve import load

CONIC_RAW_ACCEPT = 1e-6  # Clarabel's raw answer must reach this independent residual
ITERATE_ACCEPT = 10.0  # ssn/homotopy: independent residual ≤ ITERATE_ACCEPT · tol
POLISH_STEPS = 3  # the labelled polishing line (never compared)


def _methods(vi) -> list[str]:
    if vi.Lambda.quasi:  # Coulomb / contact-only Tresca: Newton and the Tresca fixed point
        return ["ssn", "fixed_point"]
    methods = ["ssn"]
    if vi.structure != "symmetric":
        methods.append("homotopy")
    if vi.structure != "general":
        methods.append("conic")
    return methods


def _run(plugin, model, meth: str, tol: float) -> vi_core.Solution:
    """The scene's problem solved by `meth` (`pipeline.solve_model`: with the plug-in's outer
    iteration, e.g. electrical contact, around each method)."""
    # the fixed point's Tresca problems by an interior point method where it applies: a path
    # independent of Newton's active sets (homotopy for a general A)
    inner = "conic" if model.vi.structure != "general" else "homotopy"
    extra = {"conic": {"polish": 0}, "fixed_point": {"inner": inner}}.get(meth, {})
    return pipeline.solve_model(plugin, model, method=meth, tol=tol, **extra)


def _states(plugin, model, sol: vi_core.Solution) -> np.ndarray | None:
    """The contact states (k,) of an answer by the plug-in's `contact_state` (vi_core.states at
    the answer's own residual), None where the plug-in or the scene has no contact."""
    if not hasattr(plugin, "contact_state") or getattr(model, "contact", True) is None:
        return None
    return np.asarray(plugin.contact_state(model, sol)["state"], dtype=object)


def _state_line(a: str, b: str, cmp: dict, la: np.ndarray, lb: np.ndarray) -> str:
    """The failure line of a states disagreement: the node count and the states each says."""
    bad = cmp["disagree_nodes"]
    kinds = Counter(f"{a} {la[i]} / {b} {lb[i]}" for i in bad)
    said = ", ".join(f"{k} at {n}" for k, n in kinds.items())
    return f"{a} / {b}: contact states disagree at {len(bad)} node(s) ({said}; nodes {bad[:8]})"


def _own_ok(meth: str, sol: vi_core.Solution) -> bool:
    if meth == "conic":
        return sol.info.get("status") == "optimal"
    return bool(sol.converged)


def _check_level(scene, plugin, level, tol) -> tuple[bool, dict]:
    model = plugin.build(scene, level)
    vi = model.vi
    methods = _methods(vi)
    print(f"\n{scene.name} level {model.level}: n = {vi.n}, m = {vi.m}, A {vi.structure}")
    if vi.structure == "symmetric" and not vi.Lambda.quasi:
        print("homotopy not run: for a symmetric A it is one call of its oracle (ssn)")
    print(
        f"{'method':<12}{'own test':>9}{'iter':>6}{'own res.':>11}{'checker':>11}{'time [s]':>10}"
    )
    sols, kkts, checkers, reasons = {}, {}, {}, []
    for meth in methods:
        sol = _run(plugin, model, meth, tol)
        # judged on the problem the answer must solve (with an outer iteration: frozen at it)
        checkers[meth] = Checker.of(pipeline.problem_at(plugin, model, sol))
        k = checkers[meth](sol.u, sol.lam)
        sols[meth], kkts[meth] = sol, k
        own = _own_ok(meth, sol)
        need = CONIC_RAW_ACCEPT if meth == "conic" else ITERATE_ACCEPT * tol
        if not own:
            reasons.append(f"{meth} failed its own test")
        if not k.relative <= need:
            reasons.append(f"{meth}: independent residual {k.relative:.1e} > {need:.0e}")
        label = "conic raw" if meth == "conic" else meth
        print(
            f"{label:<12}{'pass' if own else 'FAIL':>9}{sol.iterations:>6}{sol.residual:>11.2e}"
            f"{k.relative:>11.2e}{sol.time:>10.2f}"
        )
    labels = {m: _states(plugin, model, s) for m, s in sols.items()}  # each None or (k,)
    outer = {m: s.info["outer"] for m, s in sols.items() if "outer" in s.info}
    if outer:
        steps = ", ".join(f"{m} {o['iterations']}" for m, o in outer.items())
        print(f"each method inside the {next(iter(outer.values()))['what']}: steps {steps}")
    best = min(methods, key=lambda m: kkts[m].relative)
    checker = checkers[best]
    kappa = checker.inverse_norm(sols[best].u, sols[best].lam)
    print(f"condition: est‖J⁻¹‖₁ = {kappa:.3g} at the {best} answer (equilibrated)")
    print(f"{'pair':<20}{'diff u':>11}{'diff λ':>11}{'allowed':>11}")
    pairs = []
    for i, a in enumerate(methods):
        for b in methods[i + 1 :]:
            # the answer with the smaller residual is the reference of the relative difference
            x, y = (a, b) if kkts[a].relative >= kkts[b].relative else (b, a)
            c = checker.compare((sols[x].u, sols[x].lam), (sols[y].u, sols[y].lam), kappa)
            pairs.append({"a": a, "b": b, **c})
            within = max(c["diff_u"], c["diff_lam"]) <= c["allowed"]
            if not within:
                reasons.append(f"{a} / {b} differ beyond allowed")
            print(
                f"{a + ' / ' + b:<20}{c['diff_u']:>11.2e}{c['diff_lam']:>11.2e}"
                f"{c['allowed']:>11.2e}{'' if within else '  BEYOND'}"
            )
    for pair in pairs:  # the contact states, node by node
        la, lb = labels.get(pair["a"]), labels.get(pair["b"])
        if la is None or lb is None:
            continue
        cmp = node_states.compare(la, lb)
        pair["states"] = cmp
        line = (
            f"states {pair['a']} / {pair['b']}: {cmp['nodes']} nodes, agree {cmp['agree']}, "
            f"ambiguous {cmp['ambiguous']}, disagree {cmp['disagree']}"
        )
        print(line + ("  DISAGREE" if cmp["disagree"] else ""))
        if cmp["disagree"]:
            reasons.append(_state_line(pair["a"], pair["b"], cmp, la, lb))
    polish = None
    if "conic" in sols and vi.m:
        raw = sols["conic"]
        frozen = pipeline.problem_at(plugin, model, raw)  # the problem conic's answer solves
        pol = vi_core.solve(frozen, "ssn", tol=tol, max_iter=POLISH_STEPS, u0=raw.u, lam0=raw.lam)
        up, lp = checkers["conic"].scaled(pol.u, pol.lam)
        ur, lr = checkers["conic"].scaled(raw.u, raw.lam)
        move = float(np.linalg.norm(np.concatenate([up - ur, lp - lr])))
        move /= max(float(np.linalg.norm(np.concatenate([up, lp]))), 1e-300)
        polish = {
            "steps": pol.iterations,
            "residual_before": kkts["conic"].relative,
            "residual_after": checkers["conic"](pol.u, pol.lam).relative,
            "relative_change": move,
        }
        print(
            f"conic+polish (labelled, not compared): {pol.iterations} Newton step(s) from "
            f"Clarabel's answer, residual {polish['residual_before']:.1e} → "
            f"{polish['residual_after']:.1e}, moved by {move:.1e}"
        )
    record = {
        "level": model.level,
        "unknowns": vi.n + vi.m,
        "structure": vi.structure,
        "methods": {
            k: {
                "converged": _own_ok(k, v),
                "iterations": v.iterations,
                "residual": kkts[k].relative,
                "solver_residual": v.residual,
                "complementarity": kkts[k].complementarity,
                "time_s": v.time,
                "outer_iterations": v.info.get("outer", {}).get("iterations"),
                "states": None if labels[k] is None else node_states.counts(labels[k]),
            }
            for k, v in sols.items()
        },
        "pairs": pairs,
        "inverse_norm": kappa,
        "max_difference": max((max(p["diff_u"], p["diff_lam"]) for p in pairs), default=0.0),
        "polish": polish,
        "rho": None,
        "t0_paper": None,
        "contraction_observed": None,
        "contraction_bound": None,
    }
    if "homotopy" in sols:
        record.update(_homotopy_report(sols["homotopy"].info))
    ok = not reasons
    record["ok"] = ok
    record["failures"] = reasons
    return ok, record


def _homotopy_report(h: dict) -> dict:
    rates = h.get("rates") or [float("nan")]
    bound = h.get("rate_bound", float("nan"))
    rho, t0 = h.get("rho", float("nan")), h.get("t0_paper", float("nan"))
    t0_text = f"{t0:.2e}" if isinstance(t0, float) else str(t0)
    if bound > 0 and h.get("rates"):
        contraction = (
            f"observed contraction {rates[-1]:.4f} vs (s - tau) rho = {bound:.4f} "
            f"(ratio {rates[-1] / bound:.2f})"
        )
    else:
        contraction = "no fixed-point iteration"
    print(
        f"homotopy: rho = {rho:.4f}, levels {len(h.get('levels', [])) - 1}, {contraction}; "
        f"paper's t0 (3.11) = {t0_text}"
    )
    return {
        "rho": h.get("rho"),
        "t0_paper": h.get("t0_paper"),
        "contraction_observed": rates[-1],
        "contraction_bound": bound,
    }


def cmd_check(args: argparse.Namespace) -> int:
    """Compare the raw answers of ssn, homotopy and conic per level; exit status 1 if a method
    fails or a pair differs beyond `allowed` (module docstring)."""
    if args.levels is not None and args.level is not None:
        raise SceneError(
            "--levels", args.levels, f"either --level or --levels, not both (--level {args.level})"
        )
    loaded = load(args)
    scene, plugin = loaded.scene, loaded.plugin
    if args.levels is not None:
        option, text = "--levels", args.levels
        a, b = options.level_range(args.levels)
    else:
        lev, option = resources.requested_level(args.level, plugin, scene)
        text, (a, b) = str(lev), (lev, lev)
    resources.check_levels(plugin, scene, (a, b), option, text, args.force)
    outputs = [] if args.json is None else [Output(args.json, "--json", "json")]
    with claim(outputs, scene.files(), overwrite=args.overwrite) as run:
        return _check(scene, plugin, range(a, b + 1), args.tol, run.files.get("--json"))


def _check(scene, plugin, levels, tol, target) -> int:
    records, ok = [], True
    for level in levels:
        # in a worker thread: a signal ends the run even inside SuperLU or Clarabel
        good, rec = signals.interruptible(_check_level, scene, plugin, level, tol)
        ok = ok and good
        records.append(rec)
        if good:
            print(
                f"agree: largest difference {rec['max_difference']:.2e}, every pair within allowed"
            )
        else:
            print("DISAGREE: " + "; ".join(rec["failures"]))
    if target is not None:
        target.write(jsonable({"scene": scene.name, "records": records}))
    return 0 if ok else 1
