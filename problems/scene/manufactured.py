"""The generators of the shipped manufactured scenes, 2D `manufactured` (docs/manufactured.md) and
3D `manufactured3d` (docs/fem3d.md, "Manufactured 3D solution"); need sympy.

sympy is NOT a dependency: it is only used to *write* the scenes, whose expressions are plain
strings. Both are a BaTiO3 block (poled along the vertical axis) on a rigid foundation with
known exact (u, φ, λ); the derivation of the data from the fields (`_balance`: σ, D, f0 = −Div σ,
q0 = div D), the shared constants and the scene text are written once, for any dimension (taken
from the fields: `scene_text` of `generate(2)` or `generate(3)`).

2D, a block [0, 2] × [0, 1]:

    u1 = U (m(x)(1 + y) + c y),        m(x) = max(x − a, 0)³   (stick for x < a, slip for x > a)
    u2 = U y (0.4 sin(πx/2) − 1)
    φ  = Φ (y (1 + 0.5 cos(πx/2)) + 0.1 (1 − y) sin(πx/4))

with the side tractions σn and charges D·n, the bottom charge, λ = −σn on Γ3 and
g = λ·τ + G0 max(a − x, 0)².

3D, a box [0, 1] × [0, 1] × [0, 0.5] in bilateral Tresca contact on its bottom z = 0 (outward
normal −e_z). With X = x − cx, Y = y − cy, s = X² + Y² (the squared distance to the point
(cx, cy) outside the contact face) and m(s) = max(s − s0, 0)³:

    u_x = U ((k m(s) (1 + z) + c z) X + 0.3 z² sin(πy))
    u_y = U ((k m(s) (1 + z) + c z) Y + 0.2 z² cos(πx))
    u_z = U z (0.4 sin(πx/2) cos(πy/2) − 1)
    φ   = Φ (0.1 s (1 − 2z) + z (1 + 0.5 cos(πx/2) sin(πy/2)))

On z = 0: u_z = 0 (bilateral), u_t = U k m(s) (X, Y): zero on the stick disc s < s0, radial from
(cx, cy) on the slip zone (a slip direction turning by about 70° over the face). For a 6mm
crystal poled along z, σ_xz = c44 γ_xz + e15 ∂φ/∂x, so λ_t = (σ_xz, σ_yz) = F(s) (X, Y) with
F = c44 U (k m + c) + 0.2 e15 Φ > 0: parallel to the slip. g = |λ_t| + G0 max(s0 − s, 0)²
(= |λ_t| on the slip zone, strictly above it inside the stick disc); λ = −σn = (σ_xz, σ_yz, σ_zz)
on Γ3 as a Cartesian vector.

Regenerate with ``python -m problems.scene.manufactured > problems/scenes/manufactured.toml``
and ``python -m problems.scene.manufactured 3 > problems/scenes/manufactured3d.toml``.
"""

from __future__ import annotations

import sys

from fem.tensors import VOIGT_PAIRS

# Parameters of the manufactured solutions (docs/manufactured.md, docs/fem3d.md).
U_SCALE = 1.0e-4  # m
PHI_SCALE = 1.0e5  # V  (≈ sqrt(c33/κ33) · 1 m · 1e-4 · 0.3)
C_SHEAR = 0.5  # ∂u_t/∂(vertical) at the contact face = U (m + c) > 0, so λ·τ > 0
G_EXCESS = 4.0e6  # Pa: g − |λ_t| = G0 (distance into the stick zone)² there
MATERIAL = "BaTiO3"
# 2D
X_RANGE, Y_RANGE = (0.0, 2.0), (0.0, 1.0)
A_STICK = 0.8  # stick on [0, a), slip on (a, 2]
# 3D
BOX = ((0.0, 1.0), (0.0, 1.0), (0.0, 0.5))
CENTRE = (-0.3, -0.2)  # (cx, cy), outside the contact face: the slip direction is smooth
S0 = 1.2  # stick on s < s0 (a disc of radius 1.095 about the centre: 46 % of the face)
K_SLIP = 0.2  # weight of m(s) in u_t
SIDES = {  # boundary part → outward normal
    "left": (-1, 0, 0),
    "right": (1, 0, 0),
    "front": (0, -1, 0),
    "back": (0, 1, 0),
}
DIGITS = 15  # significant digits of the numbers in the generated 3D expressions
VOIGT_2D = ((0, 0), (1, 1), (0, 1))  # (xx, yy, xy)


def _balance(u: list, phi, xs: tuple) -> tuple:
    """σ (d × d), D (d), f0 = −Div σ (d) and q0 = div D of the fields u (d), φ of the
    coordinates `xs` for MATERIAL poled along the vertical axis, with the gradients ∇u ([k][i] =
    ∂u_k/∂x_i) and ∇φ; sympy expressions."""
    import sympy as sp

    from problems.scene.materials import crystal, plane_strain

    d = len(xs)
    mat = crystal(MATERIAL, dim=d) if d == 3 else plane_strain(crystal(MATERIAL, dim=2))
    C, e, kap = (sp.Matrix(a.tolist()) for a in (mat.C, mat.e, mat.kappa))
    pairs = VOIGT_2D if d == 2 else [tuple(p) for p in VOIGT_PAIRS.tolist()]
    G = [[sp.diff(w, v) for v in xs] for w in u]
    eps = sp.Matrix([G[i][i] if i == j else G[i][j] + G[j][i] for i, j in pairs])  # Voigt
    grad_phi = sp.Matrix([sp.diff(phi, v) for v in xs])
    sig_v = C * eps + e.T * grad_phi
    D = e * eps - kap * grad_phi
    index = {**{p: k for k, p in enumerate(pairs)}, **{p[::-1]: k for k, p in enumerate(pairs)}}
    sig = [[sig_v[index[i, j]] for j in range(d)] for i in range(d)]
    f0 = [-sum(sp.diff(sig[i][j], xs[j]) for j in range(d)) for i in range(d)]
    q0 = sum(sp.diff(D[j], xs[j]) for j in range(d))
    return G, grad_phi, sig, D, f0, q0


def generate(dim: int = 2) -> dict:
    """Derive every field of the manufactured scene of dimension `dim` with sympy; returns
    {name: expression(s)}."""
    return _fields_2d() if dim == 2 else _fields_3d()


def _fields_2d() -> dict:
    import sympy as sp

    x, y = sp.symbols("x y", real=True)
    m0, m1, m2 = sp.symbols("m0 m1 m2", real=True)  # m, m', m'' of m(x) = max(x − a, 0)³
    mfun = sp.Function("m")
    U, Phi, c = (sp.Float(v) for v in (U_SCALE, PHI_SCALE, C_SHEAR))
    u1 = U * (mfun(x) * (1 + y) + c * y)
    u2 = U * y * (sp.Rational(2, 5) * sp.sin(sp.pi * x / 2) - 1)
    phi = Phi * (
        y * (1 + sp.cos(sp.pi * x / 2) / 2) + sp.Rational(1, 10) * (1 - y) * sp.sin(sp.pi * x / 4)
    )
    G, E, sig, D, f0, q0 = _balance([u1, u2], phi, (x, y))
    sub = {
        sp.Derivative(mfun(x), (x, 2)): m2,
        sp.Derivative(mfun(x), x): m1,
        mfun(x): m0,
    }
    mtext = {
        "m0": f"maximum(x - {A_STICK}, 0)**3",
        "m1": f"3*maximum(x - {A_STICK}, 0)**2",
        "m2": f"6*maximum(x - {A_STICK}, 0)",
    }

    def text(expr, at_y=None) -> str:
        expr = expr.subs(sub)
        if at_y is not None:
            expr = expr.subs(y, at_y)
        s = str(sp.expand(sp.simplify(expr)))
        for k in ("m2", "m1", "m0"):
            s = s.replace(k, f"({mtext[k]})")
        return s

    lam_n, lam_t = -sig[1][1], sig[0][1]  # λ = −σn, n = (0, −1): λ = (σ_xy, σ_yy); λ·n = −σ_yy
    g = f"{text(lam_t, 0)} + {G_EXCESS!r}*maximum({A_STICK} - x, 0)**2"
    return {
        "u": [text(u1), text(u2)],
        "grad_u": [[text(w) for w in row] for row in G],
        "phi": text(phi),
        "grad_phi": [text(E[0]), text(E[1])],
        "lam": [text(lam_n, 0), text(lam_t, 0)],
        "body_force": [text(f0[0]), text(f0[1])],
        "free_charge": text(q0),
        "traction_left": [text(-sig[0][0]), text(-sig[0][1])],  # n = (−1, 0)
        "traction_right": [text(sig[0][0]), text(sig[0][1])],  # n = (1, 0)
        "charge_left": text(-D[0]),
        "charge_right": text(D[0]),
        "charge_bottom": text(-D[1], 0),  # n = (0, −1)
        "g": g,
    }


def _fields_3d() -> dict:
    import sympy as sp

    x, y, z = sp.symbols("x y z", real=True)
    maximum = sp.Function("maximum")

    class m0(sp.Function):  # noqa: N801 (sympy function classes print by their name)
        """m(s) = max(s − s0, 0)³ and its derivatives m1 = m', m2 = m''."""

        def fdiff(self, argindex=1):
            return m1(self.args[0])

    class m1(sp.Function):  # noqa: N801
        def fdiff(self, argindex=1):
            return m2(self.args[0])

    class m2(sp.Function):  # noqa: N801
        pass

    U, Phi, k, c = (sp.Float(v) for v in (U_SCALE, PHI_SCALE, K_SLIP, C_SHEAR))
    X, Y = x - sp.Float(CENTRE[0]), y - sp.Float(CENTRE[1])
    s = X**2 + Y**2
    a = k * m0(s) * (1 + z) + c * z
    u = [
        U * (a * X + sp.Float(0.3) * z**2 * sp.sin(sp.pi * y)),
        U * (a * Y + sp.Float(0.2) * z**2 * sp.cos(sp.pi * x)),
        U * z * (sp.Float(0.4) * sp.sin(sp.pi * x / 2) * sp.cos(sp.pi * y / 2) - 1),
    ]
    phi = Phi * (
        sp.Float(0.1) * s * (1 - 2 * z)
        + z * (1 + sp.cos(sp.pi * x / 2) * sp.sin(sp.pi * y / 2) / 2)
    )
    G, E, sig, D, f0, q0 = _balance(u, phi, (x, y, z))

    def text(expr, at_z=None) -> str:
        if at_z is not None:
            expr = expr.subs(z, at_z)
        expr = expr.replace(m2, lambda t: 6 * maximum(t - S0, 0))
        expr = expr.replace(m1, lambda t: 3 * maximum(t - S0, 0) ** 2)
        expr = expr.replace(m0, lambda t: maximum(t - S0, 0) ** 3)
        return _balanced(sp.N(sp.expand(expr), DIGITS))

    def traction(n) -> list:
        return [sum(sig[i][j] * n[j] for j in range(3)) for i in range(3)]

    lam = [sig[0][2], sig[1][2], sig[2][2]]  # λ = −σn, n = −e_z
    lt = sp.sqrt(lam[0].subs(z, 0) ** 2 + lam[1].subs(z, 0) ** 2)
    out = {
        "u": [text(w) for w in u],
        "grad_u": [[text(d) for d in row] for row in G],
        "phi": text(phi),
        "grad_phi": [text(d) for d in E],
        "lam": [text(w, 0) for w in lam],
        "body_force": [text(w) for w in f0],
        "free_charge": text(q0),
        "charge_bottom": text(-D[2], 0),
        "g": f"{text(lt, 0)} + {G_EXCESS!r}*maximum({S0} - ({text(s)}), 0)**2",
    }
    for side, n in SIDES.items():
        out[f"traction_{side}"] = [text(w) for w in traction(n)]
        out[f"charge_{side}"] = text(sum(D[j] * n[j] for j in range(3)))
    return out


def _balanced(expr) -> str:
    """The text of a sympy expression with long sums split into a balanced tree of groups
    (the scene parser refuses syntax trees deeper than MAX_DEPTH; a flat sum of n terms is n
    deep)."""
    import sympy as sp

    if not expr.is_Add or len(expr.args) <= 4:
        return str(expr)
    terms = expr.args
    half = len(terms) // 2
    left = _balanced(sp.Add(*terms[:half], evaluate=False))
    right = _balanced(sp.Add(*terms[half:], evaluate=False))
    return f"({left} + {right})"


def toml_value(v) -> str:
    """A field (an expression text or a nested list of them) as a TOML value."""
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(w) for w in v) + "]"
    return f'"{v}"'


GEOMETRY = (
    f'geometry = {{ kind = "rectangle", x = [{X_RANGE[0]}, {X_RANGE[1]}], '
    f'y = [{Y_RANGE[0]}, {Y_RANGE[1]}], cells = [4, 2], element = "triangle" }}'
)
GEOMETRY_3D = (
    f'geometry = {{ kind = "box", x = {list(BOX[0])}, y = {list(BOX[1])}, z = {list(BOX[2])}, '
    'cells = [2, 2, 1], element = "hexahedron" }'
)
# what differs between the two scene texts: header, [scene], material, geometry, side parts
HEADS = {
    2: f"""\
# Manufactured solution (docs/manufactured.md): a BaTiO3 block on a rigid foundation with a known
# exact (u, φ, λ); stick on x < {A_STICK}, slip on x > {A_STICK} along Γ3 = bottom.
# Generated by `python -m problems.scene.manufactured` (sympy, offline); do not edit by hand.
# Units: m, Pa, V, C.

format = 2  # the scene format (mixvi schema)

[scene]
title = "Manufactured solution: BaTiO3 block, Tresca contact with stick and slip"
plugin = "contact"
level = 2

[bodies.block]
material = "{MATERIAL}"
{GEOMETRY}
""",
    3: f"""\
# Manufactured 3D solution (docs/fem3d.md): a BaTiO3 box poled along z in bilateral Tresca
# contact with a rigid foundation on its bottom, with a known exact (u, φ, λ): stick on the disc
# (x + {-CENTRE[0]})² + (y + {-CENTRE[1]})² < {S0}, slip outside it along directions radial from
# ({CENTRE[0]}, {CENTRE[1]}). Generated by `python -m problems.scene.manufactured 3` (sympy,
# offline); do not edit by hand. Units: m, Pa, V, C.

format = 2

[scene]
title = "Manufactured 3D solution: BaTiO3 box, Tresca friction discs with stick and slip"
plugin = "contact"
level = 1

[bodies.block]
material = {{ name = "{MATERIAL}", poling = [0.0, 0.0, 1.0] }}
{GEOMETRY_3D}
""",
}
SIDE_PARTS = {  # the [[traction]] and [[charge]] parts on the sides, in the order written
    2: [("traction", "left"), ("traction", "right"), ("charge", "left"), ("charge", "right")],
    3: [(kind, side) for side in SIDES for kind in ("traction", "charge")],
}
OUTPUT = {2: '\n[output]\npotential_along = "block.bottom"\n', 3: ""}


def _part(kind: str, boundary: str, value: str) -> str:
    return f'\n[[bodies.block.{kind}]]\nboundary = "{boundary}"\nvalue = {value}\n'


def scene_text(fields: dict) -> str:
    """The TOML text of the manufactured scene from `generate()`'s fields (2D or 3D: the
    dimension is the length of u)."""
    f = {key: toml_value(v) for key, v in fields.items()}
    d = len(fields["u"])
    sides = "".join(_part(kind, side, f[f"{kind}_{side}"]) for kind, side in SIDE_PARTS[d])
    return (
        HEADS[d]
        + f"body_force = {f['body_force']}\nfree_charge = {f['free_charge']}\n"
        + _part("displacement", "top", f["u"])
        + _part("potential", "top", f["phi"])
        + sides
        + _part("charge", "bottom", f["charge_bottom"])
        + f'\n[contact]\nslave = "block.bottom"\nmaster = "rigid"\ng = {f["g"]}\n'
        + OUTPUT[d]
        + "\n[exact]\n"
        + "".join(f"{k} = {f[k]}\n" for k in ("u", "grad_u", "phi", "grad_phi", "lam"))
    )


if __name__ == "__main__":
    print(scene_text(generate(int(sys.argv[1]) if len(sys.argv) > 1 else 2)), end="")
