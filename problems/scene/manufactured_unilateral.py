"""The generator of the shipped scene `unilateral_manufactured` (docs/verification.md,
"A unilateral manufactured solution"); needs sympy (only to *write* the scene, whose
expressions are plain strings).

An elastic block [0, 2] × [0, 1] (E, ν, plane strain) above a curved rigid obstacle, in
unilateral contact with Tresca friction (where it touches) on its bottom Γ3 (outward normal
n = (0, −1), τ = (1, 0)), with a known exact (u, λ) whose contact boundary has all four zones,
the transitions at points of Γ3 chosen off the mesh nodes:

    separation  x < a     gap − u_n > 0, λ = 0
    stick       a < x < b u_n = gap, λ_n > 0, |λ_t| < g, s = u_t = 0
    slip        x > b     u_n = gap, λ_n > 0, λ_t = g, s > 0 (λ_t s = g |s|)

The method of manufactured solutions, backwards from the boundary: choose the traces on Γ3
(with p_k(t) = max(t, 0)^k)

    s(x)   = u_1(x, 0)  = S p3(x − b)
    u_n(x) = −u_2(x, 0) = gap(x) − D p3(a − x),    gap(x) = U (G0 + G2 (x − c)²) (curved)
    λ_n(x) = P p2(x − a),    λ_t(x) = T p2(x − a),    g(x) = λ_t(x) + K p2(b − x)

and make u take them: u_1 = s + y A(x) + y² r_1(x, y), u_2 = −u_n + y B(x) + y² r_2(x, y)
with r_k smooth interior terms (no trace, no traction on Γ3) and A, B solved from
λ = −σ(u)n = (σ_xy, σ_yy) on y = 0, i.e. σ_xy(x, 0) = λ_t and σ_yy(x, 0) = −λ_n, which is
linear in (A, B) for given s', u_n' (`_first_order`). Then the body force f = −Div σ(u), the
side tractions σn and the top displacement follow from u; λ is the trace of σ(u), so the data
make u the solution of the contact problem exactly (the conditions hold pointwise, checked by
tests/problems/scene/test_manufactured_unilateral.py).

Regenerate with ``python -m problems.scene.manufactured_unilateral >
problems/scenes/unilateral_manufactured.toml``.
"""

from __future__ import annotations

from problems.scene.manufactured import VOIGT_2D, toml_value

E_MODULUS, NU = 1.0e10, 0.3  # Pa, −
U_SCALE = 1.0e-3  # m
A_CONTACT = 0.6  # separation on [0, a), contact on (a, 2]
B_SLIP = 1.3  # stick on (a, b), slip on (b, 2]
C_OBSTACLE = 1.2  # the obstacle's lowest point (its nearest to the block)
G0, G2 = 0.5, 0.8  # gap = U (G0 + G2 (x − c)²)
D_SEPARATION = 2.0e-3  # m: gap − u_n = D (a − x)³ on the separation zone
S_SLIP = 1.0e-3  # m: s = S (x − b)³ on the slip zone
P_NORMAL = 4.0e7  # Pa: λ_n = P (x − a)²
T_SHEAR = 1.5e7  # Pa: λ_t = T (x − a)²
K_STICK = 4.0e8  # Pa: g − λ_t = K (b − x)² on the stick zone
INTERIOR = (0.3, 0.2)  # weights of the interior terms r_1, r_2 (× U)
DIGITS = 15  # significant digits of the numbers in the generated expressions
X_RANGE, Y_RANGE = (0.0, 2.0), (0.0, 1.0)


def _pos():
    """The sympy function p(t, k) = max(t, 0)^k, differentiated as k p(t, k − 1) and printed
    in the scene's expression language (k = 0: the step (1 + sign t)/2)."""
    import sympy as sp

    class p(sp.Function):  # noqa: N801 (sympy function classes print by their name)
        def fdiff(self, argindex=1):
            t, k = self.args
            if k == 0:
                raise ValueError("p(t, 0) is a step: its derivative is not a function")
            return k * p(t, k - 1)

        def _sympystr(self, printer):
            t, k = self.args[0], int(self.args[1])
            arg = printer.doprint(t)
            if k == 0:
                return f"(0.5 + 0.5*sign({arg}))"
            return f"maximum({arg}, 0)" + ("" if k == 1 else f"**{k}")

    return p


def generate() -> dict:
    """Every field of the scene, derived with sympy: {name: expression text(s)}."""
    import sympy as sp

    from problems.scene.materials import isotropic_plane_strain

    x, y = sp.symbols("x y", real=True)
    p = _pos()

    def f(v: float):  # exact rationals: the cancellations on Γ3 are exact
        return sp.nsimplify(v, rational=True)

    U = f(U_SCALE)
    a, b, c = f(A_CONTACT), f(B_SLIP), f(C_OBSTACLE)
    gap = U * (f(G0) + f(G2) * (x - c) ** 2)
    un = gap - f(D_SEPARATION) * p(a - x, 3)
    s = f(S_SLIP) * p(x - b, 3)
    lam_n = f(P_NORMAL) * p(x - a, 2)
    lam_t = f(T_SHEAR) * p(x - a, 2)
    g = lam_t + f(K_STICK) * p(b - x, 2)
    C = sp.Matrix(isotropic_plane_strain(E_MODULUS, NU).tolist()).applyfunc(f)
    A, B = _first_order(C, s, un, lam_n, lam_t, x)
    r1 = f(INTERIOR[0]) * U * sp.sin(sp.pi * x / 2) * (1 + y)
    r2 = f(INTERIOR[1]) * U * sp.cos(sp.pi * x / 3)
    u = [s + y * A + y**2 * r1, -un + y * B + y**2 * r2]
    G = [[sp.diff(w, v) for v in (x, y)] for w in u]
    eps = sp.Matrix([G[i][i] if i == j else G[i][j] + G[j][i] for i, j in VOIGT_2D])
    sv = C * eps  # (σ_xx, σ_yy, σ_xy)
    sig = [[sv[0], sv[2]], [sv[2], sv[1]]]
    body = [-sum(sp.diff(sig[i][j], v) for j, v in enumerate((x, y))) for i in range(2)]

    def text(expr, at_y=None) -> str:
        if at_y is not None:
            expr = expr.subs(y, at_y)
        return str(sp.N(sp.expand(expr), DIGITS))

    return {
        "u": [text(w) for w in u],
        "grad_u": [[text(d) for d in row] for row in G],
        "lam": [text(-sig[1][1], 0), text(sig[0][1], 0)],  # n = (0, −1): λ = (σ_xy, σ_yy)
        "body_force": [text(w) for w in body],
        "traction_left": [text(-sig[0][0]), text(-sig[1][0])],  # n = (−1, 0)
        "traction_right": [text(sig[0][0]), text(sig[1][0])],  # n = (1, 0)
        "gap": text(gap),
        "g": text(g),
    }


def _first_order(C, s, un, lam_n, lam_t, x) -> tuple:
    """(A, B): the first y-derivatives of u_1 and u_2 on y = 0 that make σ_xy = λ_t and
    σ_yy = −λ_n there, for u_1 = s, u_2 = −u_n on y = 0 and the Voigt matrix C (3 × 3)."""
    import sympy as sp

    Aa, Bb = sp.symbols("A B")
    eps = sp.Matrix([sp.diff(s, x), Bb, Aa - sp.diff(un, x)])  # (ε_xx, ε_yy, 2ε_xy) at y = 0
    sv = C * eps
    sol = sp.solve([sv[2] - lam_t, sv[1] + lam_n], [Aa, Bb], dict=True)[0]
    return sol[Aa], sol[Bb]


HEAD = f"""\
# A manufactured unilateral solution (docs/verification.md, "A unilateral manufactured
# solution"): an elastic block above a curved rigid obstacle, unilateral contact with Tresca
# friction where it touches, with a known exact (u, λ): separation for x < {A_CONTACT}, stick on
# ({A_CONTACT}, {B_SLIP}), slip for x > {B_SLIP} along Γ3 = bottom; gap(x) = {U_SCALE} ({G0} +
# {G2} (x − {C_OBSTACLE})²). Generated by `python -m problems.scene.manufactured_unilateral`
# (sympy, offline); do not edit by hand. Units: m, Pa.

format = 2  # the scene format (mixvi schema)

[scene]
title = "Manufactured unilateral contact: separation, stick and slip zones on a curved obstacle"
plugin = "contact"
level = 2

[bodies.block]
material = {{ kind = "isotropic", E = {E_MODULUS!r}, nu = {NU!r} }}
geometry = {{ kind = "rectangle", x = [{X_RANGE[0]}, {X_RANGE[1]}], y = [{Y_RANGE[0]}, \
{Y_RANGE[1]}], cells = [4, 2], element = "triangle" }}
"""


def scene_text(fields: dict) -> str:
    """The TOML text of the scene from `generate()`'s fields."""
    v = {key: toml_value(w) for key, w in fields.items()}
    part = '\n[[bodies.block.{}]]\nboundary = "{}"\nvalue = {}\n'
    return (
        HEAD
        + f"body_force = {v['body_force']}\n"
        + part.format("displacement", "top", v["u"])
        + part.format("traction", "left", v["traction_left"])
        + part.format("traction", "right", v["traction_right"])
        + '\n[contact]\nslave = "block.bottom"\nmaster = "rigid"\nlaw = "unilateral"\n'
        + f'friction = "tresca"\ng = {v["g"]}\ngap = {v["gap"]}\n'
        + "\n[exact]\n"
        + "".join(f"{k} = {v[k]}\n" for k in ("u", "grad_u", "lam"))
    )


if __name__ == "__main__":
    print(scene_text(generate()), end="")
