"""Safe arithmetic expressions of (x, y) or (x, y, z) — and of the load parameter t in a scene
with a `[load_path]` — for scene values, parsed with `ast`, never `eval`.

Grammar (checked before anything is evaluated)::

    expr     := number | name | expr OP expr | (+|-) expr | expr CMP expr | call | ( expr )
    OP       := + | - | * | / | **
    CMP      := < | <= | > | >=            (one comparison, gives 0.0 / 1.0)
    name     := x | y | z | t | pi | e (z in a 3D scene, t with a load path: the caller checks)
    call     := FUNCTION ( expr, ... )     positional arguments only, exactly ARITY of them

Functions and their arities: one argument — sin cos tan exp log sqrt abs tanh arctan sinh cosh
sign; two — arctan2 minimum maximum; three — where(condition, a, b). Limits: at most MAX_LENGTH
characters, nesting depth at most MAX_DEPTH, number literals finite and of size ≤ MAX_MAGNITUDE.
Each function is called through a fixed-arity wrapper, so no keyword or extra positional argument
(NumPy's ufunc `out=`) can reach NumPy, and the arguments are copies: an expression never writes
into the caller's arrays. A result that is not finite or larger than MAX_MAGNITUDE (division by
zero, overflow, log of a negative number) is refused by `Expression.__call__` with the scene
field path and the expression text. Example: ``"-0.05*(1 - x**2)"``.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable

import numpy as np

MAX_LENGTH = 2000  # characters of one expression
MAX_DEPTH = 32  # nesting depth of the syntax tree
MAX_MAGNITUDE = 1e100  # |number| in a scene; larger ones overflow when squared in assembly


def _unary(f: Callable) -> Callable:
    return lambda a: f(a)


def _binary(f: Callable) -> Callable:
    return lambda a, b: f(a, b)


# name → (arity, fixed-arity wrapper): the only way a scene reaches a NumPy function
FUNCTIONS: dict[str, tuple[int, Callable]] = {
    **{
        n: (1, _unary(getattr(np, n)))
        for n in "sin cos tan exp log sqrt abs tanh arctan sinh cosh sign".split()
    },
    **{n: (2, _binary(getattr(np, n))) for n in ("arctan2", "minimum", "maximum")},
    "where": (3, lambda c, a, b: np.where(c != 0, a, b)),
}
CONSTANTS = {"pi": np.pi, "e": np.e}
_BINOPS = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_CMPOPS = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge}
ALLOWED = (
    "a number or an arithmetic expression of x, y (and z in a 3D scene) and, in a scene with a "
    "[load_path], its load parameter t (numbers, pi, e, + - * / **, comparisons, and the "
    "functions "
    + ", ".join(f"{n}/{a}" for n, (a, _) in sorted(FUNCTIONS.items()))
    + " (name/arity))"
)


class ExpressionError(ValueError):
    """The text is not an allowed expression, or its value is not finite."""


def _check(node: ast.AST, variables: tuple[str, ...], depth: int = 0) -> None:
    if depth > MAX_DEPTH:
        raise ExpressionError(f"nested deeper than {MAX_DEPTH} levels")
    d = depth + 1
    if isinstance(node, ast.Expression):
        _check(node.body, variables, d)
    elif isinstance(node, ast.Constant):
        v = node.value
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ExpressionError(f"constant {v!r} is not a number")
        try:
            ok = math.isfinite(float(v)) and abs(float(v)) <= MAX_MAGNITUDE
        except OverflowError:
            ok = False
        if not ok:
            raise ExpressionError(f"number literal not finite or above {MAX_MAGNITUDE:g}")
    elif isinstance(node, ast.Name):
        if node.id not in variables and node.id not in CONSTANTS:
            raise ExpressionError(f"unknown name {node.id!r}")
    elif isinstance(node, ast.BinOp):
        if type(node.op) not in _BINOPS:
            raise ExpressionError(f"operator {type(node.op).__name__} is not allowed")
        _check(node.left, variables, d)
        _check(node.right, variables, d)
    elif isinstance(node, ast.UnaryOp):
        if not isinstance(node.op, ast.UAdd | ast.USub):
            raise ExpressionError(f"operator {type(node.op).__name__} is not allowed")
        _check(node.operand, variables, d)
    elif isinstance(node, ast.Compare):
        if len(node.ops) != 1 or type(node.ops[0]) not in _CMPOPS:
            raise ExpressionError("only single comparisons < <= > >= are allowed")
        _check(node.left, variables, d)
        _check(node.comparators[0], variables, d)
    elif isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            raise ExpressionError(f"function {ast.unparse(node.func)!r} is not allowed")
        name = node.func.id
        arity = FUNCTIONS[name][0]
        if node.keywords:
            raise ExpressionError(f"{name}(): keyword arguments are not allowed")
        if any(isinstance(a, ast.Starred) for a in node.args):
            raise ExpressionError(f"{name}(): *arguments are not allowed")
        if len(node.args) != arity:
            raise ExpressionError(
                f"{name}() takes {arity} argument{'s' if arity > 1 else ''}, got {len(node.args)}"
            )
        for a in node.args:
            _check(a, variables, d)
    else:
        raise ExpressionError(f"{type(node).__name__} is not allowed")


def _eval(node: ast.AST, env: dict) -> np.ndarray:
    if isinstance(node, ast.Constant):
        return np.float64(node.value)
    if isinstance(node, ast.Name):
        return env[node.id] if node.id in env else np.float64(CONSTANTS[node.id])
    if isinstance(node, ast.BinOp):
        return _BINOPS[type(node.op)](_eval(node.left, env), _eval(node.right, env))
    if isinstance(node, ast.UnaryOp):
        v = _eval(node.operand, env)
        return -v if isinstance(node.op, ast.USub) else +v
    if isinstance(node, ast.Compare):
        op = _CMPOPS[type(node.ops[0])]
        return np.asarray(op(_eval(node.left, env), _eval(node.comparators[0], env)), float)
    if isinstance(node, ast.Call):
        return FUNCTIONS[node.func.id][1](*[_eval(a, env) for a in node.args])
    raise AssertionError(type(node))  # unreachable: _check admitted only the nodes above


def parse(text: str, variables: tuple[str, ...] = ("x", "y")) -> ast.Expression:
    """The checked syntax tree of `text` (ExpressionError naming what is not allowed)."""
    if not isinstance(text, str):
        raise ExpressionError(f"{type(text).__name__} is not an expression")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"longer than {MAX_LENGTH} characters ({len(text)})")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as err:
        raise ExpressionError(f"syntax error: {err.msg}") from None
    except (ValueError, RecursionError, MemoryError) as err:  # null bytes, absurd nesting
        raise ExpressionError(f"not parseable ({type(err).__name__})") from None
    _check(tree, variables)
    return tree


def compile_expression(
    text: str, variables: tuple[str, ...] = ("x", "y")
) -> Callable[..., np.ndarray]:
    """Compile `text` into a vectorised function of `variables` (ExpressionError if not allowed).

    The function returns an array of the broadcast shape of its arguments, NaN/inf included:
    finiteness is judged by the caller (`problems.scene.fields.Expression`), which knows the
    scene field.
    """
    body = parse(text, variables).body

    def fn(*args: np.ndarray) -> np.ndarray:
        if len(args) != len(variables):
            raise TypeError(f"expected {len(variables)} arguments, got {len(args)}")
        env = {v: np.array(a, dtype=float, copy=True) for v, a in zip(variables, args, strict=True)}
        with np.errstate(all="ignore"):
            try:
                out = np.asarray(_eval(body, env), dtype=float)
            except (OverflowError, ZeroDivisionError):  # Python-level scalar arithmetic
                out = np.asarray(np.nan)
        shape = np.broadcast_shapes(*(np.shape(a) for a in args)) if args else ()
        return np.broadcast_to(out, shape).copy()

    fn.__doc__ = text
    return fn
