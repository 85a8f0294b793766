"""Command-line values shared by every command: levels, level ranges, tolerances.

Each parser raises SceneError naming the option, the value and what is allowed (exit status 2).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from problems.errors import SceneError

MAX_LEVEL = 12
DEFAULT_SCENE = "paper_two_body"


def solver_options(args: argparse.Namespace) -> dict:
    """The keywords of `pipeline.solve` and `solve_path` from `mixvi solve`'s options
    (--solver, --tol, --cold, --linear-solver)."""
    return {
        "method": args.solver,
        "tol": args.tol,
        "cold": args.cold,
        "linear_solver": args.linear_solver,
    }


def number(text: str, kind: type, ok: Callable[[Any], bool], what: str) -> Any:
    """argparse type body: `kind(text)` where it converts and `ok` holds, else
    argparse.ArgumentTypeError "'text': what"."""
    try:
        v = kind(text)
    except ValueError:
        v = None
    if v is None or not ok(v):
        raise argparse.ArgumentTypeError(f"{text!r}: {what}")
    return v


def level(text: str) -> int:
    """argparse type: a refinement level, an integer 0 … MAX_LEVEL (the scene's own cap, from
    its memory estimate, is checked once the scene is read: `resources.check_levels`)."""
    what = f"a level is an integer from 0 to {MAX_LEVEL}"
    return number(text, int, lambda v: 0 <= v <= MAX_LEVEL, what)


# --accuracy presets: (level, tol); measured time and error on the paper scene in the README
ACCURACY = {"fast": (1, 1e-6), "balanced": (2, 1e-8), "fine": (3, 1e-10)}


def accuracy(text: str) -> str | float:
    """argparse type of --accuracy: a preset name of `ACCURACY`, or a relative error estimate
    in (0, 1) for the adaptive loop (`problems.commands.adapt`)."""
    if text in ACCURACY:
        return text
    what = f"one of {', '.join(ACCURACY)}, or a relative error estimate in (0, 1)"
    return number(text, float, lambda v: 0.0 < v < 1.0, what)


def tol(text: str) -> float:
    """argparse type: a relative residual tolerance in (0, 1)."""
    return number(text, float, lambda v: 0.0 < v < 1.0, "a tolerance is a number in (0, 1)")


def level_range(text: str, option: str = "--levels") -> tuple[int, int]:
    """'A..B' or 'N' → (A, B) as written (SceneError naming `option` unless both are
    integers); whether 0 ≤ A ≤ B ≤ the scene's cap is checked once the scene is read
    (`resources.check_levels`, which knows the cap)."""
    lo, sep, hi = text.strip().partition("..")
    try:
        return (int(lo), int(hi)) if sep else (int(lo), int(lo))
    except ValueError:
        raise SceneError(
            option,
            text,
            "expected A..B with integers 0 ≤ A ≤ B ≤ N (N: the scene's largest level that "
            "fits in memory), or one level, e.g. 0..2",
        ) from None


def names(text: str, option: str, allowed: list[str] | tuple[str, ...]) -> list[str]:
    """'a,b' → ['a', 'b']: a non-empty comma-separated list of distinct names from `allowed`
    (SceneError naming `option`, the value and the allowed names otherwise)."""
    items = [s.strip() for s in text.split(",")]
    what = "a non-empty comma-separated list of distinct names from: " + ", ".join(allowed)
    if not text.strip() or any(not s for s in items) or len(set(items)) != len(items):
        raise SceneError(option, text, what)
    bad = [s for s in items if s not in allowed]
    if bad:
        raise SceneError(option, bad[0], what)
    return items


def workers(text: str) -> int:
    """argparse type: a number of Dask worker processes, 1 … 256."""
    try:
        n = int(text)
    except ValueError:
        n = 0
    if not 1 <= n <= 256:
        raise SceneError("--workers", text, "a whole number of worker processes, 1 … 256")
    return n


def add_run_options(p: argparse.ArgumentParser) -> None:
    """The options `mixvi study` and `mixvi sweep` share: where the cases run (--workers N on
    a local Dask cluster, or --scheduler ADDRESS), --overwrite and --force."""
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=workers,
        default=None,
        help="run the cases as Dask tasks on a local cluster of N single-threaded worker "
        'processes (optional extra: pip install -e ".[dask]")',
    )
    where.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the cases on a running dask.distributed cluster, e.g. tcp://host:8786",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="write into a folder that holds other files (nothing is deleted)",
    )
    p.add_argument("--force", action="store_true", help="try levels above the scene's memory cap")
