"""The commands' progress bars: drawn on stderr only when it is a terminal, never with
TQDM_DISABLE set, and not with `mixvi study --no-progress`.

tqdm reads TQDM_DISABLE once, when it is imported, and only as the default of `disable`: a bar
made with an explicit `disable=None` (tqdm's "on a terminal only") ignores it. `bar` reads it
itself each time, as tqdm does (any non-empty value disables). Every command's bar is made
here (tests/problems/commands/test_progress.py keeps it so).
"""

from __future__ import annotations

import os
from typing import Any

from tqdm import tqdm


def bar(*, shown: bool = True, **kwargs: Any) -> tqdm:
    """A tqdm bar on stderr (`kwargs` as tqdm's, `disable` excepted), drawn only if `shown`,
    stderr is a terminal and TQDM_DISABLE is not set to a non-empty value."""
    off = not shown or bool(os.environ.get("TQDM_DISABLE", ""))
    return tqdm(disable=True if off else None, **kwargs)
