"""`mixvi bench --baseline OLD.json`: this run's cases against an earlier run's, so that a
slowdown between two commits is seen the day it lands (the direct path once became 19x slower
unnoticed).

Cases are matched by (scene, level, solver, linear solver). For each pair the table shows the
new ÷ old factor of the CPU time of the nonlinear solve and of the one linear solve (CPU time:
`time.process_time` of the child, which moves much less with the machine's load than the wall
clock), of the peak resident memory, and the Newton iterations old → new. A case is REGRESSED
when a factor exceeds its limit (`LIMITS`; CPU times below `FLOOR` seconds in both runs are too
short to compare and shown as "-"), when its iterations or unknowns changed, or when it ran
before and fails now. Taken on another machine (platform or core count differ) the absolute
times say nothing: only the dimensionless ratio nonlinear ÷ linear, the iterations and the
unknowns are compared, and the table says so.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from problems.errors import SceneError

# The same code run twice on this machine under other jobs' load: CPU times of 0.5-1.5 s moved
# by up to x1.6, of 2-5 s by up to x1.36, the ratio nonlinear / linear by up to x1.19, the peak
# memory not at all (docs/benchmarks.md, "Benchmark baselines"). The limits sit above that.
LIMITS = {"cpu_nonlinear_s": 2.0, "cpu_linear_s": 2.0, "cpu_ratio": 1.5, "peak_mem_mb": 1.25}
FLOOR = 1.0  # CPU seconds: shorter times are compared by their iterations only


def read_baseline(path: str) -> dict:
    """The bench JSON at `path` (written by `mixvi bench`); SceneError naming --baseline."""
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise SceneError("--baseline", path, "an existing bench JSON file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise SceneError(
            "--baseline", path, f"a bench JSON file written by mixvi bench ({err})"
        ) from None
    if not (
        isinstance(data, dict)
        and isinstance(data.get("records"), list)
        and all(isinstance(r, dict) and "scene" in r for r in data["records"])
    ):
        raise SceneError(
            "--baseline", path, "a bench JSON file written by mixvi bench (no 'records' list)"
        )
    return data


def _key(r: dict) -> tuple:
    return (r["scene"], r.get("level"), r.get("solver", "ssn"), r.get("linear_solver"))


def same_machine(old: dict, new: dict) -> bool:
    """Whether two runs' `machine` records name the same platform and core count."""
    a, b = old.get("machine") or {}, new.get("machine") or {}
    return all(a.get(k) == b.get(k) for k in ("platform", "cpus"))


def compare(old: dict, new: dict) -> list[dict]:
    """One row per case of `new` found in `old`: the factors new ÷ old (None where not
    compared), the iterations and unknowns of both, and `regressed` with its reasons."""
    before = {_key(r): r for r in old["records"]}
    here = same_machine(old, new)
    fields = list(LIMITS) if here else ["cpu_ratio"]
    rows = []
    for r in new["records"]:
        o = before.get(_key(r))
        if o is None:
            continue
        row: dict[str, Any] = {
            "case": _key(r),
            "iterations": (o.get("iterations"), r.get("iterations")),
            "unknowns": (o.get("unknowns"), r.get("unknowns")),
            "factors": {},
            "reasons": [],
        }
        if r.get("error") or not r.get("converged"):
            if not o.get("error") and o.get("converged"):
                row["reasons"].append(f"fails now: {r.get('error') or 'not converged'}")
        elif not o.get("error"):
            for f in fields:
                a, b = o.get(f), r.get(f)
                timed = "cpu_nonlinear_s" if f == "cpu_ratio" else f  # the time a factor rests on
                short = f.startswith("cpu_") and max(o.get(timed) or 0, r.get(timed) or 0) < FLOOR
                if a is None or b is None or a <= 0 or short:
                    row["factors"][f] = None
                    continue
                row["factors"][f] = b / a
                if b / a > LIMITS[f]:
                    row["reasons"].append(f"{f} x{b / a:.2f} (limit x{LIMITS[f]:g})")
            for what in ("iterations", "unknowns"):
                if row[what][0] != row[what][1]:
                    row["reasons"].append(f"{what} {row[what][0]} -> {row[what][1]}")
        row["regressed"] = bool(row["reasons"])
        rows.append(row)
    return rows


def table(rows: list[dict], here: bool) -> list[str]:
    """The comparison as printed lines."""
    head = "same machine" if here else "another machine: only nonlinear/linear, iterations"
    lines = [
        f"\nagainst the baseline ({head}; new / old, limits "
        + ", ".join(f"{k} x{v:g}" for k, v in LIMITS.items())
        + ")",
        f"{'scene':<18}{'level':>6}{'solver':>8}{'linear':>8}{'cpu nonlin':>12}"
        f"{'cpu linear':>12}{'nonlin/lin':>12}{'peak':>8}{'iter':>9}  verdict",
    ]
    for row in rows:
        scene, level, solver, linear = row["case"]
        f = row["factors"]

        def fmt(k: str, width: int, f: dict = f) -> str:
            v = f.get(k)
            return f"{'-' if v is None else f'x{v:.2f}':>{width}}"

        it = "{}->{}".format(*row["iterations"])
        verdict = "REGRESSED: " + "; ".join(row["reasons"]) if row["regressed"] else "ok"
        lines.append(
            f"{scene:<18}{level!s:>6}{solver:>8}{linear or '-':>8}{fmt('cpu_nonlinear_s', 12)}"
            f"{fmt('cpu_linear_s', 12)}{fmt('cpu_ratio', 12)}{fmt('peak_mem_mb', 8)}"
            f"{it:>9}  {verdict}"
        )
    if not rows:
        lines.append("(no case of this run is in the baseline)")
    return lines
