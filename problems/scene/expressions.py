"""Safe arithmetic expressions of (x, y) for scene values — parsed with `ast`, never `eval`.

Allowed: numbers, x, y, pi, e, + − * / ** and unary ±, comparisons (giving 0/1 arrays),
and the functions sin cos tan exp log sqrt abs tanh arctan arctan2 sinh cosh minimum maximum
where sign. Example: ``"-0.05*(1 - x**2)"``.
"""

from __future__ import annotations

import ast
import operator
from collections.abc import Callable

import numpy as np

FUNCTIONS: dict[str, Callable] = {
    name: getattr(np, name)
    for name in (
        "sin cos tan exp log sqrt abs tanh arctan arctan2 sinh cosh minimum maximum where sign"
    ).split()
}
CONSTANTS = {"pi": np.pi, "e": np.e}
_BINOPS = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_CMPOPS = {
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
}
ALLOWED = (
    "an arithmetic expression of x, y (numbers, pi, e, + - * / **, comparisons, and "
    + ", ".join(sorted(FUNCTIONS))
    + ")"
)


class ExpressionError(ValueError):
    """The text is not an allowed expression."""


def _check(node: ast.AST, variables: tuple[str, ...]) -> None:
    if isinstance(node, ast.Expression):
        _check(node.body, variables)
    elif isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, int | float):
            raise ExpressionError(f"constant {node.value!r} is not a number")
    elif isinstance(node, ast.Name):
        if node.id not in variables and node.id not in CONSTANTS:
            raise ExpressionError(f"unknown name {node.id!r}")
    elif isinstance(node, ast.BinOp):
        if type(node.op) not in _BINOPS:
            raise ExpressionError(f"operator {type(node.op).__name__} is not allowed")
        _check(node.left, variables)
        _check(node.right, variables)
    elif isinstance(node, ast.UnaryOp):
        if not isinstance(node.op, ast.UAdd | ast.USub):
            raise ExpressionError(f"operator {type(node.op).__name__} is not allowed")
        _check(node.operand, variables)
    elif isinstance(node, ast.Compare):
        if len(node.ops) != 1 or type(node.ops[0]) not in _CMPOPS:
            raise ExpressionError("only single comparisons < <= > >= are allowed")
        _check(node.left, variables)
        _check(node.comparators[0], variables)
    elif isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            raise ExpressionError(f"function {ast.unparse(node.func)!r} is not allowed")
        if node.keywords:
            raise ExpressionError("keyword arguments are not allowed")
        for a in node.args:
            _check(a, variables)
    else:
        raise ExpressionError(f"{type(node).__name__} is not allowed")


def _eval(node: ast.AST, env: dict) -> np.ndarray:
    if isinstance(node, ast.Constant):
        return np.float64(node.value)
    if isinstance(node, ast.Name):
        return env[node.id] if node.id in env else CONSTANTS[node.id]
    if isinstance(node, ast.BinOp):
        return _BINOPS[type(node.op)](_eval(node.left, env), _eval(node.right, env))
    if isinstance(node, ast.UnaryOp):
        v = _eval(node.operand, env)
        return -v if isinstance(node.op, ast.USub) else +v
    if isinstance(node, ast.Compare):
        op = _CMPOPS[type(node.ops[0])]
        return op(_eval(node.left, env), _eval(node.comparators[0], env)).astype(float)
    if isinstance(node, ast.Call):
        return FUNCTIONS[node.func.id](*[_eval(a, env) for a in node.args])
    raise AssertionError(type(node))


def compile_expression(
    text: str, variables: tuple[str, ...] = ("x", "y")
) -> Callable[..., np.ndarray]:
    """Compile `text` into a vectorised function of `variables` (ExpressionError if not allowed)."""
    if len(text) > 2000:
        raise ExpressionError("expression longer than 2000 characters")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as err:
        raise ExpressionError(f"syntax error: {err.msg}") from None
    _check(tree, variables)
    body = tree.body

    def fn(*args: np.ndarray) -> np.ndarray:
        env = {v: np.asarray(a, dtype=float) for v, a in zip(variables, args, strict=True)}
        with np.errstate(all="ignore"):
            out = np.asarray(_eval(body, env), dtype=float)
        shape = np.broadcast_shapes(*(np.shape(a) for a in args)) if args else ()
        return np.broadcast_to(out, shape).copy()

    fn.__doc__ = text
    return fn
