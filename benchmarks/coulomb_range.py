"""The range of the friction coefficient F over which the two Coulomb paths converge and agree
on a scene: semismooth Newton on the combined map and the fixed point on Tresca
problems g ← F λ_n (vi_core.tresca_fixed_point), each Tresca problem solved by `inner`; for
contact scenes (2D and 3D) with law = "unilateral".

    python benchmarks/coulomb_range.py SCENE [--F 0,0.1,0.3] [--levels 0..2]
        [--inner conic|ssn|homotopy] [--set KEY=VALUE ...] [--json FILE]

For each level and F (the scene's [contact] F replaced by a constant) it prints one row: Newton
steps and its residual by the independent checker (vi_core.kkt), the fixed-point iterations,
inner Newton/interior-point steps and measured contraction, the Newton steps of the unilateral
Tresca problem with the constant bound g = F·(mean Coulomb pressure), and the difference of
the two Coulomb answers against what their residuals allow (`Checker.compare`). A row is
"agree" when both converge (residual ≤ tol by the checker too) and differ within the allowed
amount, else it says which path did not converge. Nothing is returned as an answer by a path
that did not converge (vi_core says converged=False).

Exit status 0 when every row agrees, 1 otherwise (the range is then the rows that agree).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from problems.errors import SceneError
from problems.plugins.contract import problem_at, solve_model
from problems.plugins.registry import for_scene
from problems.scene import load_scene
from vi_core.kkt import Checker

ACCEPT = 10.0  # a path's independent residual must be ≤ ACCEPT · tol (as `mixvi check`)


def _scene(name: str, overrides: list[str], F: float, friction: str = "coulomb", g: float = 0.0):
    scene = load_scene(name, overrides)
    ct = scene.data.get("contact")
    if not ct or ct.get("law") != "unilateral":
        raise SceneError("contact.law", (ct or {}).get("law"), "'unilateral' (a Coulomb scene)")
    ct.pop("g", None)
    ct.pop("F", None)
    ct["friction"] = friction
    ct["F" if friction == "coulomb" else "g"] = float(F if friction == "coulomb" else g)
    return scene


def _zones(st: dict) -> tuple[int, int, int, float]:
    """(open, stick, slip, mean λ_n where touching) of a contact state: 2D's (per multiplier
    row: touch over the normal rows, touch_t over the tangential ones) or 3D's (per surface
    node, with its state names)."""
    touch = st["touch"]
    mean_p = float(np.mean(st["lam_n"][touch])) if touch.any() else 0.0
    slip = int(st["slip"].sum())
    if "has_t" in st:  # 3D
        state = st["state"]
        return int((state == "open").sum()), int((state == "stick").sum()), slip, mean_p
    state = st["state"]
    return int(np.sum(st["normal_state"] == "open")), int(np.sum(state == "stick")), slip, mean_p


def measure(name: str, F: float, level: int, inner: str, overrides=(), tol=1e-10) -> dict:
    """One row (module docstring) of scene `name` at friction coefficient F and `level`."""
    scene = _scene(name, list(overrides), F)
    plugin = for_scene(scene)
    model = plugin.build(scene, level)
    # the scene's problem (with the plug-in's outer iteration, e.g. a [contact.electrical]
    # fixed point, around each path), each answer judged on the problem it must solve
    newton = solve_model(plugin, model, method="ssn", tol=tol)
    fixed = solve_model(plugin, model, method="fixed_point", tol=tol, inner=inner)
    vi = problem_at(plugin, model, newton)
    check = Checker.of(vi)
    res_n = check(newton.u, newton.lam).relative
    res_f = Checker.of(problem_at(plugin, model, fixed))(fixed.u, fixed.lam).relative
    ok_n = newton.converged and res_n <= ACCEPT * tol
    ok_f = fixed.converged and res_f <= ACCEPT * tol
    row = {
        "scene": name,
        "level": model.level,
        "F": F,
        "unknowns": vi.n + vi.m,
        "newton_converged": bool(ok_n),
        "newton_steps": newton.iterations,
        "newton_residual": res_n,
        "fp_converged": bool(ok_f),
        "fp_iterations": fixed.iterations,
        "fp_inner_steps": int(sum(fixed.info.get("inner_iterations", []))),
        "contraction": fixed.info.get("contraction"),
        "fp_residual": res_f,
    }
    if ok_n:
        row["open"], row["stick"], row["slip"], mean_p = _zones(plugin.contact_state(model, newton))
        tresca = plugin.build(_scene(name, list(overrides), F, "tresca", F * mean_p), level)
        t_sol = solve_model(plugin, tresca, method="ssn", tol=tol)
        row["tresca_newton_steps"] = t_sol.iterations if t_sol.converged else None
    if ok_n and ok_f:
        kappa = check.inverse_norm(newton.u, newton.lam)
        c = check.compare((fixed.u, fixed.lam), (newton.u, newton.lam), kappa)
        row.update(diff=max(c["diff_u"], c["diff_lam"]), allowed=c["allowed"])
        row["verdict"] = "agree" if row["diff"] <= row["allowed"] else "DIFFER"
    else:
        which = [p for p, ok in (("ssn", ok_n), ("fixed point", ok_f)) if not ok]
        row["verdict"] = "not converged: " + ", ".join(which)
    return row


def _print(rows: list[dict]) -> None:
    print(
        f"{'level':>5}{'F':>8}{'Newton':>7}{'Tresca':>7}{'FP it':>6}{'inner':>6}"
        f"{'contr.':>8}{'open':>5}{'stick':>6}{'slip':>5}{'diff':>10}{'allowed':>10}  verdict"
    )
    for r in rows:

        def f(k, fmt, r=r):
            v = r.get(k)
            return format(v, fmt) if v is not None else "–"

        print(
            f"{r['level']:>5}{r['F']:>8g}{r['newton_steps']:>7}{f('tresca_newton_steps', 'd'):>7}"
            f"{r['fp_iterations']:>6}{r['fp_inner_steps']:>6}{f('contraction', '.3f'):>8}"
            f"{f('open', 'd'):>5}{f('stick', 'd'):>6}{f('slip', 'd'):>5}{f('diff', '.1e'):>10}"
            f"{f('allowed', '.1e'):>10}  {r['verdict']}"
        )


def main(argv: list[str] | None = None) -> int:
    """Command line (module docstring); returns the exit status."""
    p = argparse.ArgumentParser(prog="python benchmarks/coulomb_range.py")
    p.add_argument("scene")
    p.add_argument("--F", default="0,0.1,0.3,1,3", help="comma-separated values of F")
    p.add_argument("--levels", default="1", help="a level or LO..HI")
    p.add_argument("--inner", default="conic", choices=["conic", "ssn", "homotopy"])
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--json", type=Path, default=None)
    a = p.parse_args(argv)
    try:
        values = [float(v) for v in a.F.split(",")]
        lo, _, hi = a.levels.partition("..")
        levels = range(int(lo), int(hi or lo) + 1)
    except ValueError:
        print(f"--F {a.F!r} / --levels {a.levels!r}: numbers, e.g. 0,0.1 and 0..2", file=sys.stderr)
        return 2
    if any(v < 0 for v in values):
        print(f"--F {a.F!r}: friction coefficients ≥ 0", file=sys.stderr)
        return 2
    try:
        rows = [measure(a.scene, F, lev, a.inner, a.set) for lev in levels for F in values]
    except SceneError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    _print(rows)
    if a.json is not None:
        if a.json.exists():
            print(f"--json {a.json}: exists; not replaced", file=sys.stderr)
            return 2
        a.json.write_text(json.dumps(rows, indent=1) + "\n")
    return 0 if all(r["verdict"] == "agree" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
