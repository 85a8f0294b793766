"""Numbers for JSON: numpy scalars and arrays as Python numbers and lists."""

from __future__ import annotations

import numpy as np


def jsonable(x):
    """`x` with numpy scalars and arrays turned into Python numbers and lists."""
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x
