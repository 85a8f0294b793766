"""Value types of 3D scenes: expressions of (x, y, z), 3-vectors, 3D intervals and cell counts.

`Expression3` is an `Expression` (same grammar, limits, refusals and field paths) whose
variables are x, y and z; it is called as f(x, y, z). `Vector3` is three of them.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import AfterValidator, Field
from pydantic_core import PydanticCustomError

from problems.errors import SceneError

from .expressions import ALLOWED, MAX_MAGNITUDE
from .fields import Expression, Integer, Number, _nonnegative

VARIABLES = ("x", "y", "z", "t")  # t: the load parameter (scenes with a [load_path] only)
ALLOWED_3D = ALLOWED.replace("of x, y", "of x, y, z")


class Expression3(Expression):
    """A compiled scalar field f(x, y, z) of a 3D scene: a constant or an expression text."""

    VARIABLES = VARIABLES
    ALLOWED_TEXT = ALLOWED_3D

    def __call__(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:  # type: ignore[override]
        """Values at the points (x, y, z): an array of their broadcast shape (SceneError if a
        value is not finite or larger than MAX_MAGNITUDE)."""
        shape = np.broadcast_shapes(np.shape(x), np.shape(y), np.shape(z))
        if self._fn is None:
            return np.full(shape, float(self.source))
        out = self._fn(x, y, z, np.float64(self.load_t()))
        bad = ~(np.isfinite(out) & (np.abs(out) <= MAX_MAGNITUDE))
        if bad.any():
            i = np.unravel_index(int(np.argmax(bad)), shape)
            p = [float(np.broadcast_to(a, shape)[i]) for a in (x, y, z)]
            raise SceneError(
                self.path,
                self.source,
                f"an expression whose values are finite and of size ≤ {MAX_MAGNITUDE:g} on the "
                f"domain (at (x, y, z) = ({p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g}) it is "
                f"{float(out[i])!r}: a division by zero, an overflow or a function outside its "
                "domain)",
            )
        return out

    def __repr__(self) -> str:
        return f"Expression3({self.source!r})"


NonNegativeExpr3 = Annotated[Expression3, AfterValidator(_nonnegative)]
Vector3 = Annotated[list[Expression3], Field(min_length=3, max_length=3)]


def _increasing(v: list) -> list:
    if v[0] >= v[1]:
        raise PydanticCustomError("interval", "an interval [a, b] with a < b")
    return v


def _positive_ints(v: list) -> list:
    if min(v) < 1:
        raise PydanticCustomError("cells", "three positive integers [nx, ny, nz]")
    return v


def _unit(v: list) -> list:
    if not np.linalg.norm(np.asarray(v, float)) > 0:
        raise PydanticCustomError("direction", "a non-zero direction [dx, dy, dz]")
    return v


Interval = Annotated[list[Number], Field(min_length=2, max_length=2), AfterValidator(_increasing)]
Cells3 = Annotated[list[Integer], Field(min_length=3, max_length=3), AfterValidator(_positive_ints)]
Direction = Annotated[list[Number], Field(min_length=3, max_length=3), AfterValidator(_unit)]
