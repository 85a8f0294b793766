"""Value types of the scene model (pydantic), for 2D and 3D scenes: checked numbers,
expression fields, intervals, cell counts, directions.

Every type refuses what it cannot take with a pydantic error; `problems.scene.model.validate`
turns the first one into a SceneError naming the field path, the value and what is allowed.

- `Number`: an int or float (never a bool or a string), finite, of size ≤ MAX_MAGNITUDE;
  ranges are added per field with `Field(gt=..., le=...)`.
- `Expression`: a number or an expression string (`problems.scene.expressions`), compiled
  once; called as f(x, y) in a 2D scene, f(x, y, z) in a 3D one, it refuses a non-finite or
  oversized result with its field path and text (`NonNegativeExpr`: constants also checked ≥ 0
  when read); `Vector` is two or three of them (the table holding it checks it has d). z
  only in a 3D scene, the load parameter t only in a scene with a `[load_path]` (both
  checked by `problems.scene.model.validate`); an expression is evaluated at the t of the
  enclosing `load_parameter(t)` block (a load step), and outside one at the path's last t
  (`Expression.t_end`, set by validation).
- `Interval`, `IntPair`, `Point`: [a, b] pairs; `Cells`/`BoxCells`: cell counts per axis;
  `Direction`: a non-zero 3-vector (a poling axis).
"""

from __future__ import annotations

import importlib
import math
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Annotated, Any

import numpy as np
from pydantic import (
    AfterValidator,
    BeforeValidator,
    Field,
    GetCoreSchemaHandler,
    GetJsonSchemaHandler,
)
from pydantic_core import PydanticCustomError, core_schema

from problems.errors import SceneError

from .expressions import ALLOWED, MAX_LENGTH, MAX_MAGNITUDE, ExpressionError, compile_expression


def _finite(v: Any) -> bool:
    try:
        return math.isfinite(float(v)) and abs(float(v)) <= MAX_MAGNITUDE
    except OverflowError:
        return False


def number_value(v: Any) -> Any:
    """A number as written: int or float, not bool, finite and of size ≤ MAX_MAGNITUDE."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise PydanticCustomError("number", "a number (not {kind})", {"kind": type(v).__name__})
    if not _finite(v):
        raise PydanticCustomError(
            "number", "a finite number of size ≤ {limit}", {"limit": f"{MAX_MAGNITUDE:g}"}
        )
    return v


def integer_value(v: Any) -> Any:
    """An int, not a bool (nor a float with an integer value)."""
    if isinstance(v, bool) or not isinstance(v, int):
        raise PydanticCustomError("integer", "an integer (not {kind})", {"kind": type(v).__name__})
    return v


def text_value(v: Any) -> Any:
    """A string, never a number converted to one."""
    if not isinstance(v, str):
        raise PydanticCustomError("string", "a string (not {kind})", {"kind": type(v).__name__})
    return v


Number = Annotated[float, BeforeValidator(number_value)]
Integer = Annotated[int, BeforeValidator(integer_value)]
Text = Annotated[str, BeforeValidator(text_value)]


VARIABLES = ("x", "y", "z", "t")  # z: 3D scenes only; t: the load parameter (scenes with a
# [load_path] only)
_LOAD_T: ContextVar[float | None] = ContextVar("load_parameter", default=None)


@contextmanager
def load_parameter(t: float) -> Iterator[None]:
    """Inside the block every scene expression is evaluated at load parameter `t` (one step of
    a load path: `problems.pipeline.load_path`)."""
    token = _LOAD_T.set(float(t))
    try:
        yield
    finally:
        _LOAD_T.reset(token)


class Expression:
    """A compiled scalar field f(x, y) (2D) or f(x, y, z) (3D) of a scene: a constant or an
    expression text.

    `path` (the dotted scene field, set by `problems.scene.model.validate`) and `source` name
    it in every refusal. Calling it never changes its arguments. `uses_t`: the text names the
    load parameter t, taken from the enclosing `load_parameter` block, else `t_end` (the last
    t of the scene's load path, set by validation; None: the scene has no load path).
    """

    def __init__(self, source: float | str):
        self.source = source
        self.path = "(expression)"
        self.t_end: float | None = None
        if isinstance(source, str):
            self._fn = compile_expression(source, VARIABLES)
            self.constant = False
            names = _names(source)
            self.uses_t, self.uses_z = "t" in names, "z" in names
        else:
            self._fn = None
            self.constant = True
            self.uses_t = self.uses_z = False

    def load_t(self) -> float:
        """The load parameter this expression is evaluated at now (0 if it does not use t;
        SceneError if it does and the scene has no load path)."""
        if not self.uses_t:
            return 0.0
        t = _LOAD_T.get()
        t = self.t_end if t is None else t
        if t is None:
            raise SceneError(self.path, self.source, NO_LOAD_PATH)
        return t

    def __call__(self, *coords: np.ndarray) -> np.ndarray:
        """Values at the points whose coordinates are `coords` ((x, y) in 2D, (x, y, z) in
        3D): an array of their broadcast shape (SceneError if any value is not finite or
        larger than MAX_MAGNITUDE)."""
        if len(coords) not in (2, 3) or (self.uses_z and len(coords) == 2):
            raise TypeError(f"{self!r} takes the coordinates x, y{', z' * self.uses_z}")
        names = VARIABLES[: len(coords)]
        shape = np.broadcast_shapes(*(np.shape(c) for c in coords))
        if self._fn is None:
            return np.full(shape, float(self.source))
        t = self.load_t()
        out = self._fn(*coords[:2], coords[2] if len(coords) == 3 else 0.0, np.float64(t))
        bad = ~(np.isfinite(out) & (np.abs(out) <= MAX_MAGNITUDE))
        if bad.any():
            i = np.unravel_index(int(np.argmax(bad)), shape)
            at = ", ".join(f"{float(np.broadcast_to(c, shape)[i]):.6g}" for c in coords)
            at_t = f", t = {t:.6g}" if self.uses_t else ""
            raise SceneError(
                self.path,
                self.source,
                f"an expression whose values are finite and of size ≤ {MAX_MAGNITUDE:g} on the "
                f"domain (at ({', '.join(names)}) = ({at}){at_t} it is {float(out[i])!r}: a "
                "division by zero, an overflow or a function outside its domain)",
            )
        return out

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.source!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Expression) and other.source == self.source

    __hash__ = None  # mutable path; equality by source

    @classmethod
    def parse(cls, v: Any) -> Expression:
        """A number or an expression text of VARIABLES → an Expression (pydantic error
        otherwise, listing what is allowed)."""
        if isinstance(v, cls):
            return v
        if isinstance(v, str):
            try:
                e = cls(v)
            except ExpressionError as err:
                raise PydanticCustomError(
                    "expression",
                    "{why}; allowed: {allowed}",
                    {"allowed": ALLOWED, "why": str(err)},
                ) from None
            if not (set(VARIABLES) & _names(v)):  # a constant expression: evaluate it now
                val = e._fn(*[np.zeros(1)] * len(VARIABLES))
                if not (np.isfinite(val).all() and (np.abs(val) <= MAX_MAGNITUDE).all()):
                    raise PydanticCustomError(
                        "expression",
                        "an expression with a finite value of size ≤ {limit} (this one is {val})",
                        {"limit": f"{MAX_MAGNITUDE:g}", "val": repr(float(val[0]))},
                    )
            return e
        try:
            number_value(v)
        except PydanticCustomError:
            raise PydanticCustomError("expression", "{allowed}", {"allowed": ALLOWED}) from None
        return cls(v)

    @classmethod
    def __get_pydantic_core_schema__(
        cls, source: Any, handler: GetCoreSchemaHandler
    ) -> core_schema.CoreSchema:
        return core_schema.no_info_plain_validator_function(
            cls.parse,
            serialization=core_schema.plain_serializer_function_ser_schema(lambda e: e.source),
        )

    @classmethod
    def __get_pydantic_json_schema__(
        cls, schema: core_schema.CoreSchema, handler: GetJsonSchemaHandler
    ) -> dict:
        return {
            "anyOf": [
                {"type": "number"},
                {"type": "string", "maxLength": MAX_LENGTH, "minLength": 1},
            ],
            "description": ALLOWED,
        }


NO_LOAD_PATH = (
    "an expression of the coordinates: t is the load parameter of a load path, and this scene "
    "has no [load_path] section (add one, e.g. `[load_path]` with `steps = 10`, docs/load_paths.md)"
)


Z_IN_2D = (
    "an expression of x and y: z is a coordinate of 3D scenes, and this scene's geometries are 2D"
)


def _names(text: str) -> set[str]:
    import ast

    return {n.id for n in ast.walk(ast.parse(text.strip(), mode="eval")) if isinstance(n, ast.Name)}


def _nonnegative(e: Expression) -> Expression:
    if e.constant and float(e.source) < 0:
        raise PydanticCustomError("expression", "a field ≥ 0 (a number or expression)")
    return e


NonNegativeExpr = Annotated[Expression, AfterValidator(_nonnegative)]  # constants checked now,
# expressions where they are evaluated
Vector = Annotated[list[Expression], Field(min_length=2, max_length=3)]  # d entries: checked
# against the dimension by the table that holds it (`problems.plugins.contact.bodies`)


def evaluate(components: Sequence[Expression], *coords: np.ndarray) -> np.ndarray:
    """A vector field's values: (..., len(components)) at the points whose coordinates are
    `coords` (x, y in 2D; x, y, z in 3D)."""
    return np.stack([c(*coords) for c in components], axis=-1)


def _increasing(v: list) -> list:
    if v[0] >= v[1]:
        raise PydanticCustomError("interval", "an interval [a, b] with a < b")
    return v


def _positive_ints(allowed: str) -> AfterValidator:
    """The check of a cell count per axis: every entry ≥ 1, else `allowed` is the refusal."""

    def check(v: list) -> list:
        if min(v) < 1:
            raise PydanticCustomError("cells", allowed)
        return v

    return AfterValidator(check)


def _nonzero(v: list) -> list:
    if not np.linalg.norm(np.asarray(v, float)) > 0:
        raise PydanticCustomError("direction", "a non-zero direction [dx, dy, dz]")
    return v


def _numbers(n: int) -> Any:
    return Annotated[list[Number], Field(min_length=n, max_length=n)]


def _integers(n: int) -> Any:
    return Annotated[list[Integer], Field(min_length=n, max_length=n)]


Pair = _numbers(2)
Point = Pair
Interval = Annotated[Pair, AfterValidator(_increasing)]
IntPair = _integers(2)
Cells = Annotated[IntPair, _positive_ints("two positive integers [nx, ny]")]
BoxCells = Annotated[_integers(3), _positive_ints("three positive integers [nx, ny, nz]")]
Direction = Annotated[_numbers(3), AfterValidator(_nonzero)]  # a 3D direction, not normalised


def renamed(module: str, names: dict[str, str]) -> Callable[[str], Any]:
    """The `__getattr__` of `module` that serves its former names (of before the 2D and 3D
    contact plug-ins became one) for one release, with a DeprecationWarning: `names` maps each
    to the name that replaced it, NAME in `module` itself (a former 3D name: the one type of 2D
    and 3D) or MODULE.NAME elsewhere."""

    def __getattr__(name: str) -> Any:
        if name not in names:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        where, _, new = names[name].rpartition(".")
        note = f"{module}.{name} is deprecated and goes in the next release: use {names[name]}"
        warnings.warn(note, DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(where or module), new)

    return __getattr__


__getattr__ = renamed(__name__, {"Expression3": "Expression"})
