"""Command-line values shared by every command: levels, level ranges, tolerances.

Each parser raises SceneError naming the option, the value and what is allowed (exit status 2).
"""

from __future__ import annotations

import argparse

from problems.errors import SceneError

MAX_LEVEL = 12
DEFAULT_SCENE = "paper_two_body"


def level(text: str) -> int:
    """argparse type: a refinement level 0 … MAX_LEVEL (exit 2 with a message otherwise)."""
    try:
        v = int(text)
    except ValueError:
        v = -1
    if not 0 <= v <= MAX_LEVEL:
        raise argparse.ArgumentTypeError(f"{text!r}: a level is an integer from 0 to {MAX_LEVEL}")
    return v


def tol(text: str) -> float:
    """argparse type: a relative residual tolerance in (0, 1)."""
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not 0.0 < v < 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: a tolerance is a number in (0, 1)")
    return v


def level_range(text: str, option: str = "--levels", cap: int = MAX_LEVEL) -> list[int]:
    """'A..B' or 'N' → the levels A … B; SceneError naming `option` unless 0 ≤ A ≤ B ≤ cap."""
    allowed = f"A..B with 0 ≤ A ≤ B ≤ {cap}, or one level N, e.g. 0..2"
    lo, sep, hi = text.partition("..")
    try:
        a, b = (int(lo), int(hi)) if sep else (int(lo), int(lo))
    except ValueError:
        raise SceneError(option, text, allowed) from None
    if not 0 <= a <= b <= cap:
        raise SceneError(option, text, allowed)
    return list(range(a, b + 1))


def levels(text: str | None, default: int | None) -> list[int | None]:
    """`--levels` if given (see `level_range`), else the single `--level` (None: the scene's)."""
    return [default] if text is None else list(level_range(text))
