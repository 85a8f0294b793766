"""Safe expressions: values, and refusal of anything but arithmetic."""

import numpy as np
import pytest

from problems.scene.expressions import ExpressionError, compile_expression


def test_values():
    x = np.linspace(-1, 1, 5)
    y = np.zeros(5)
    np.testing.assert_allclose(compile_expression("-0.05*(1 - x**2)")(x, y), -0.05 * (1 - x**2))
    np.testing.assert_allclose(
        compile_expression("where(x < 0, 1, 2)")(x, y), np.where(x < 0, 1, 2)
    )
    np.testing.assert_allclose(compile_expression("sin(pi*x)*exp(y)")(x, y), np.sin(np.pi * x))
    assert compile_expression("3")(np.zeros((2, 3)), np.zeros((2, 3))).shape == (2, 3)


@pytest.mark.parametrize(
    "text",
    [
        "__import__('os')",
        "x.real",
        "open('f')",
        "(lambda: 1)()",
        "x if y else 1",
        "[1, 2]",
        "z + 1",
        "'a'",
        "sin(x, y=1)",
        "x @ y",
        "1 +",
    ],
)
def test_refused(text):
    with pytest.raises(ExpressionError):
        compile_expression(text)


# ------------------------------------------------------------------ arity, no mutation
from problems.errors import SceneError  # noqa: E402
from problems.scene import expressions  # noqa: E402
from problems.scene.expressions import FUNCTIONS, MAX_DEPTH, MAX_LENGTH  # noqa: E402
from problems.scene.fields import Expression  # noqa: E402


def _coordinates():
    rng = np.random.default_rng(7)
    return rng.uniform(-1, 1, 50), rng.uniform(-1, 1, 50)  # (50,) each


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_every_function_with_every_wrong_arity_is_refused_and_never_writes_coordinates(name):
    """sin(x, y) was accepted: NumPy took y as the ufunc's `out` and overwrote the mesh
    coordinates. Every function, 0 … arity + 2 arguments (and a keyword): the wrong ones are
    refused before evaluation; the right one evaluates; the arrays stay byte-identical."""
    arity = FUNCTIONS[name][0]
    x, y = _coordinates()
    before = x.tobytes(), y.tobytes()
    for n in range(arity + 3):
        args = ", ".join(["x", "y", "x"][i % 3] for i in range(n))
        text = f"{name}({args})"
        if n == arity:
            out = compile_expression(text)(x, y)
            assert out.shape == x.shape
        else:
            with pytest.raises(ExpressionError, match=f"{name}\\(\\) takes {arity}"):
                compile_expression(text)(x, y)
        assert (x.tobytes(), y.tobytes()) == before, text
    kw = ", ".join(["x"] * arity) + ", out=y"
    with pytest.raises(ExpressionError, match="keyword"):
        compile_expression(f"{name}({kw})")
    assert (x.tobytes(), y.tobytes()) == before


def test_arguments_are_copies_even_for_an_in_place_operation(monkeypatch):
    """Mutation: a function that writes into its argument (as ufunc `out=` did) leaves the
    caller's arrays alone, because the evaluator hands it copies."""

    def writes(a):
        a[...] = 0.0
        return a

    monkeypatch.setitem(FUNCTIONS, "sin", (1, writes))
    x, y = _coordinates()
    before = x.tobytes()
    compile_expression("sin(x)")(x, y)
    assert x.tobytes() == before


def test_nesting_and_length_limits():
    deep = "(" * (MAX_DEPTH + 5) + "x" + ")" * (MAX_DEPTH + 5)  # parentheses do not nest the tree
    compile_expression(deep)
    nested = "sin(" * (MAX_DEPTH + 1) + "x" + ")" * (MAX_DEPTH + 1)
    with pytest.raises(ExpressionError, match="nested deeper"):
        compile_expression(nested)
    with pytest.raises(ExpressionError, match="longer than"):
        compile_expression("x+" * (MAX_LENGTH // 2) + "1")
    with pytest.raises(ExpressionError):  # far beyond the parser's own recursion limit
        compile_expression("-" * 100_000 + "x")
    with pytest.raises(ExpressionError):
        compile_expression("(" * 1500 + "x" + ")" * 1500)


def test_depth_limit_is_what_refuses(monkeypatch):
    """Mutation: without the depth limit the nested expression would be accepted."""
    nested = "sin(" * (MAX_DEPTH + 1) + "x" + ")" * (MAX_DEPTH + 1)
    monkeypatch.setattr(expressions, "MAX_DEPTH", 10**6)
    compile_expression(nested)


@pytest.mark.parametrize(
    "text", ["1e400", "10" * 200, "1j", "True", "None", "x if x else y", "x < y < 1", "\0"]
)
def test_literals_and_forms_outside_the_grammar(text):
    with pytest.raises(ExpressionError):
        compile_expression(text)


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("1/(x - x)", "division"),
        ("exp(1000*x + 1000)", "overflow"),
        ("log(x - 5)", "log of a negative"),
        ("sqrt(x - 5)", "sqrt of a negative"),
        ("10**(400*(x + 2))", "power overflow"),
        ("1e90 * 1e90 * (x + 2)", "beyond MAX_MAGNITUDE"),
    ],
)
def test_non_finite_values_are_refused_with_the_field_and_the_text(text, where):
    e = Expression.parse(text)
    e.path = "bodies.block.body_force[1]"
    x, y = _coordinates()
    with pytest.raises(SceneError) as err:
        e(x, y)
    msg = str(err.value)
    assert "bodies.block.body_force[1]" in msg and repr(text) in msg and "(x, y) = (" in msg


def test_constant_expressions_are_checked_when_read():
    from pydantic_core import PydanticCustomError

    for text in ("1/0", "10**400", "log(0)", "exp(1000)"):
        with pytest.raises(PydanticCustomError):
            Expression.parse(text)
    assert Expression.parse("2*pi")(np.zeros(3), np.zeros(3))[0] == pytest.approx(2 * np.pi)
