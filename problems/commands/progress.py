"""The commands' progress bars: drawn on stderr only when it is a terminal, never with
TQDM_DISABLE set, and not with `mixvi study --no-progress`.

tqdm reads TQDM_DISABLE once, when it is imported, and only as the default of `disable`: a bar
made with an explicit `disable=None` (tqdm's "on a terminal only") ignores it. `bar` reads it
itself each time, as tqdm does (any non-empty value disables). Every command's bar is made
here (tests/problems/commands/test_progress.py keeps it so). `newton_status` shows, beside a
bar, the Newton steps (and GMRES iterations) of the level being solved.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

from tqdm import tqdm


def bar(*, shown: bool = True, **kwargs: Any) -> tqdm:
    """A tqdm bar on stderr (`kwargs` as tqdm's, `disable` excepted), drawn only if `shown`,
    stderr is a terminal and TQDM_DISABLE is not set to a non-empty value."""
    off = not shown or bool(os.environ.get("TQDM_DISABLE", ""))
    return tqdm(disable=True if off else None, **kwargs)


def status(level: int, info: dict) -> str:
    """'L3 Newton 4 res 1.2e-05 active 412 slip 37 GMRES 58' (GMRES only on the iterative
    path; 'Newton 4…' while step 4 is still being solved, with the residual before it)."""
    k = info["step"] if info["done"] else f"{info['step']}…"
    text = (
        f"L{level} Newton {k} res {info['residual']:.1e} "
        f"active {info['active']} slip {info['slip']}"
    )
    its = info.get("krylov_iterations")
    return text if its is None else f"{text} GMRES {its}"


def newton_status(pbar: tqdm, every: float = 0.5) -> Callable[[int, dict], None]:
    """An `on_step(level, info)` (`problems.pipeline.solve`) that shows `status` after the
    bar `pbar`: at the end of every Newton step, and within a step (GMRES iterations) at most
    every `every` seconds. Nothing is drawn where the bar is not (a pipe, TQDM_DISABLE)."""
    last = [0.0]

    def on_step(level: int, info: dict) -> None:
        now = time.monotonic()
        if info["done"] or now - last[0] >= every:
            last[0] = now
            pbar.set_postfix_str(status(level, info), refresh=True)

    return on_step
