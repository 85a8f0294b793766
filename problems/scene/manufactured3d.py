"""The generator of the shipped 3D manufactured scene `manufactured3d` (docs/fem3d.md,
"Manufactured 3D solution"); needs sympy, which is not a dependency: it only *writes*
`problems/scenes/manufactured3d.toml`, whose expressions are plain strings.

A BaTiO3 box [0, 1] × [0, 1] × [0, 0.5] poled along z, in bilateral Tresca contact with a rigid
foundation on its bottom z = 0 (outward normal −e_z). With X = x − cx, Y = y − cy,
s = X² + Y² (the squared distance to the point (cx, cy) outside the contact face) and
m(s) = max(s − s0, 0)³:

    u_x = U ((k m(s) (1 + z) + c z) X + 0.3 z² sin(πy))
    u_y = U ((k m(s) (1 + z) + c z) Y + 0.2 z² cos(πx))
    u_z = U z (0.4 sin(πx/2) cos(πy/2) − 1)
    φ   = Φ (0.1 s (1 − 2z) + z (1 + 0.5 cos(πx/2) sin(πy/2)))

On z = 0: u_z = 0 (bilateral), u_t = U k m(s) (X, Y): zero on the stick disc s < s0, radial from
(cx, cy) on the slip zone (a slip direction turning by about 70° over the face). For a 6mm
crystal poled along z, σ_xz = c44 γ_xz + e15 ∂φ/∂x, so λ_t = (σ_xz, σ_yz) = F(s) (X, Y) with
F = c44 U (k m + c) + 0.2 e15 Φ > 0: parallel to the slip. g = |λ_t| + G0 max(s0 − s, 0)²
(= |λ_t| on the slip zone, strictly above it inside the stick disc). Derived: f0 = −Div σ,
q0 = div D, tractions σn and charges D·n on the four sides, the bottom charge, and the exact
λ = −σn = (σ_xz, σ_yz, σ_zz) on Γ3. Regenerate with
``python -m problems.scene.manufactured3d > problems/scenes/manufactured3d.toml``.
"""

from __future__ import annotations

from .manufactured import toml_value

BOX = ((0.0, 1.0), (0.0, 1.0), (0.0, 0.5))
CENTRE = (-0.3, -0.2)  # (cx, cy), outside the contact face: the slip direction is smooth
S0 = 1.2  # stick on s < s0 (a disc of radius 1.095 about the centre: 46 % of the face)
U_SCALE = 1.0e-4  # m
PHI_SCALE = 1.0e5  # V
K_SLIP = 0.2  # weight of m(s) in u_t
C_SHEAR = 0.5  # ∂u_t/∂z(z = 0) = U (k m + c) (X, Y)
G_EXCESS = 4.0e6  # Pa: g − |λ_t| = G0 max(s0 − s, 0)² on the stick disc
MATERIAL = "BaTiO3"
SIDES = {  # boundary part → outward normal
    "left": (-1, 0, 0),
    "right": (1, 0, 0),
    "front": (0, -1, 0),
    "back": (0, 1, 0),
}
DIGITS = 15  # significant digits of the numbers in the generated expressions


def generate() -> dict:
    """Derive every field of the scene with sympy; returns {name: expression(s)}."""
    import sympy as sp

    from .materials3d import named_6mm

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

    mat = named_6mm(MATERIAL)  # poled along z
    C, e, kap = (sp.Matrix(a.tolist()) for a in (mat.C, mat.e, mat.kappa))
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
    xyz = (x, y, z)
    G = [[sp.diff(w, v) for v in xyz] for w in u]  # [k][i] = ∂u_k/∂x_i
    eps = sp.Matrix(
        [G[0][0], G[1][1], G[2][2], G[1][2] + G[2][1], G[0][2] + G[2][0], G[0][1] + G[1][0]]
    )  # Voigt (xx, yy, zz, yz, xz, xy), engineering shears
    E = sp.Matrix([sp.diff(phi, v) for v in xyz])
    sig_v = C * eps + e.T * E
    D = e * eps - kap * E
    voigt = ((0, 5, 4), (5, 1, 3), (4, 3, 2))
    sig = [[sig_v[voigt[i][j]] for j in range(3)] for i in range(3)]
    f0 = [-sum(sp.diff(sig[i][j], xyz[j]) for j in range(3)) for i in range(3)]
    q0 = sum(sp.diff(D[j], xyz[j]) for j in range(3))

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


GEOMETRY = (
    f'{{ kind = "box", x = {list(BOX[0])}, y = {list(BOX[1])}, z = {list(BOX[2])}, '
    'cells = [2, 2, 1], element = "hexahedron" }'
)


def scene_text(fields: dict) -> str:
    """The TOML text of `scenes/manufactured3d.toml` from `generate()`'s fields."""
    f = {key: toml_value(v) for key, v in fields.items()}
    sides = "".join(
        f"""
[[bodies.block.traction]]
boundary = "{side}"
value = {f[f"traction_{side}"]}

[[bodies.block.charge]]
boundary = "{side}"
value = {f[f"charge_{side}"]}
"""
        for side in SIDES
    )
    return f"""\
# Manufactured 3D solution (docs/fem3d.md): a BaTiO3 box poled along z in bilateral Tresca
# contact with a rigid foundation on its bottom, with a known exact (u, φ, λ): stick on the disc
# (x + {-CENTRE[0]})² + (y + {-CENTRE[1]})² < {S0}, slip outside it along directions radial from
# ({CENTRE[0]}, {CENTRE[1]}). Generated by `python -m problems.scene.manufactured3d` (sympy,
# offline); do not edit by hand. Units: m, Pa, V, C.

format = 2

[scene]
title = "Manufactured 3D solution: BaTiO3 box, Tresca friction discs with stick and slip"
plugin = "contact3d"
level = 1

[bodies.block]
material = {{ name = "{MATERIAL}", poling = [0.0, 0.0, 1.0] }}
geometry = {GEOMETRY}
body_force = {f["body_force"]}
free_charge = {f["free_charge"]}

[[bodies.block.displacement]]
boundary = "top"
value = {f["u"]}

[[bodies.block.potential]]
boundary = "top"
value = {f["phi"]}
{sides}
[[bodies.block.charge]]
boundary = "bottom"
value = {f["charge_bottom"]}

[contact]
slave = "block.bottom"
master = "rigid"
g = {f["g"]}

[exact]
u = {f["u"]}
grad_u = {f["grad_u"]}
phi = {f["phi"]}
grad_phi = {f["grad_phi"]}
lam = {f["lam"]}
"""


if __name__ == "__main__":
    print(scene_text(generate()), end="")
