"""Exact solutions of scenes: the `[exact]` table, and the generator of the manufactured scene.

A scene may carry an `[exact]` table of expression fields (same safe expressions as every scene
value) giving the exact solution:

    [exact]
    u = [u1, u2]                          # displacement (m)
    grad_u = [[u1_x, u1_y], [u2_x, u2_y]]
    phi = "..."                           # potential (V), piezoelectric bodies
    grad_phi = [phi_x, phi_y]
    lam = [lam_n, lam_t]                  # λ = −σn on Γ3: λ·n and λ·τ (Pa), fields of (x, y)

`split_exact` removes the table from the scene (the plug-in does not know the key) and compiles
it. The study engine (`problems.study`) measures errors against it.

`generate()` (needs sympy, which is NOT a dependency: it is only used to *write* the shipped scene
`scenes/manufactured.toml`, whose expressions are plain strings) builds the manufactured
solution of docs/manufactured.md: a BaTiO3 block [0, 2] × [0, 1] on a rigid foundation with

    u1 = U (m(x)(1 + y) + c y),        m(x) = max(x − a, 0)³   (stick for x < a, slip for x > a)
    u2 = U y (0.4 sin(πx/2) − 1)
    φ  = Φ (y (1 + 0.5 cos(πx/2)) + 0.1 (1 − y) sin(πx/4))

and derives f0 = −Div σ, q0 = div D, the side tractions σn and charges D·n, the bottom charge,
λ = −σn on Γ3 and g = λ·τ + G0 max(a − x, 0)². Regenerate with
``python -m problems.manufactured > problems/scenes/manufactured.toml``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .errors import SceneError
from .scene import Scene, Table

# ------------------------------------------------------------------ the [exact] table
Field = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Exact:
    """Compiled exact fields; each maps (x, y) arrays to x.shape + (components...)."""

    u: Field  # → (..., 2)
    grad_u: Field  # → (..., 2, 2), [k, i] = ∂u_k/∂x_i
    phi: Field | None  # → (...)
    grad_phi: Field | None  # → (..., 2)
    lam: Field  # → (..., 2): (λ·n, λ·τ) on Γ3


def _matrix_field(t: Table, name: str) -> Field:
    """A 2×2 list of expression fields as one function → (..., 2, 2)."""
    raw = t.raw(name)
    if not (isinstance(raw, list) and len(raw) == 2 and all(isinstance(r, list) for r in raw)):
        raise SceneError(t.key(name), raw, "a 2×2 list [[a, b], [c, d]] of numbers or expressions")
    rows = [Table({"row": r}, t.key(name)).field("row", 2) for r in raw]

    def fn(x, y):
        return np.stack([r(x, y) for r in rows], axis=-2)  # (..., 2, 2)

    return fn


def split_exact(scene: Scene) -> tuple[Scene, Exact | None]:
    """The scene without its `[exact]` table, and the compiled table (None if absent)."""
    if "exact" not in scene.data:
        return scene, None
    data = dict(scene.data)
    raw = data.pop("exact")
    if not isinstance(raw, dict):
        raise SceneError("exact", raw, "a table [exact] with u, grad_u, lam (and phi, grad_phi)")
    t = Table(raw, "exact")
    exact = Exact(
        u=t.field("u", 2),
        grad_u=_matrix_field(t, "grad_u"),
        phi=t.field("phi", 1) if t.has("phi") else None,
        grad_phi=t.field("grad_phi", 2) if t.has("grad_phi") else None,
        lam=t.field("lam", 2),
    )
    if (exact.phi is None) != (exact.grad_phi is None):
        raise SceneError("exact", sorted(raw), "both phi and grad_phi, or neither")
    t.finish()
    return Scene(data=data, path=scene.path, name=scene.name), exact


# ------------------------------------------------------------------ the generator (sympy)
# Parameters of the manufactured solution (docs/manufactured.md).
X_RANGE, Y_RANGE = (0.0, 2.0), (0.0, 1.0)
A_STICK = 0.8  # stick on [0, a), slip on (a, 2]
U_SCALE = 1.0e-4  # m
PHI_SCALE = 1.0e5  # V  (≈ sqrt(c33/κ33) · 1 m · 1e-4 · 0.3)
C_SHEAR = 0.5  # u1 = U (m(x)(1 + y) + c y): ∂u1/∂y(x, 0) = U (m + c) > 0, so λ·τ > 0
G_EXCESS = 4.0e6  # Pa: g − λ·τ = G0 max(a − x, 0)² on the stick zone
MATERIAL = "BaTiO3"


def generate() -> dict:
    """Derive every field of the manufactured scene with sympy; returns {name: expression(s)}."""
    import sympy as sp

    from .materials import NAMED

    x, y = sp.symbols("x y", real=True)
    m0, m1, m2 = sp.symbols("m0 m1 m2", real=True)  # m, m', m'' of m(x) = max(x − a, 0)³
    mfun = sp.Function("m")
    mat = NAMED[MATERIAL]
    C, e, kap = (sp.Matrix(mat[k]) for k in ("C", "e", "kappa"))
    U, Phi, c, a = (sp.Float(v) for v in (U_SCALE, PHI_SCALE, C_SHEAR, A_STICK))
    u1 = U * (mfun(x) * (1 + y) + c * y)
    u2 = U * y * (sp.Rational(2, 5) * sp.sin(sp.pi * x / 2) - 1)
    phi = Phi * (
        y * (1 + sp.cos(sp.pi * x / 2) / 2) + sp.Rational(1, 10) * (1 - y) * sp.sin(sp.pi * x / 4)
    )
    eps = sp.Matrix([sp.diff(u1, x), sp.diff(u2, y), sp.diff(u1, y) + sp.diff(u2, x)])
    E = sp.Matrix([sp.diff(phi, x), sp.diff(phi, y)])
    sig = C * eps + e.T * E  # (xx, yy, xy)
    D = e * eps - kap * E  # (D_x, D_y)
    f0 = [-(sp.diff(sig[0], x) + sp.diff(sig[2], y)), -(sp.diff(sig[2], x) + sp.diff(sig[1], y))]
    q0 = sp.diff(D[0], x) + sp.diff(D[1], y)
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

    lam_n, lam_t = -sig[1], sig[2]  # λ = −σn, n = (0, −1): λ = (σ_xy, σ_yy); λ·n = −σ_yy
    g = f"{text(lam_t, 0)} + {G_EXCESS!r}*maximum({A_STICK} - x, 0)**2"
    return {
        "u": [text(u1), text(u2)],
        "grad_u": [[text(sp.diff(w, v)) for v in (x, y)] for w in (u1, u2)],
        "phi": text(phi),
        "grad_phi": [text(E[0]), text(E[1])],
        "lam": [text(lam_n, 0), text(lam_t, 0)],
        "body_force": [text(f0[0]), text(f0[1])],
        "free_charge": text(q0),
        "traction_left": [text(-sig[0]), text(-sig[2])],  # n = (−1, 0)
        "traction_right": [text(sig[0]), text(sig[2])],  # n = (1, 0)
        "charge_left": text(-D[0]),
        "charge_right": text(D[0]),
        "charge_bottom": text(-D[1], 0),  # n = (0, −1)
        "g": g,
    }


def _toml(v) -> str:
    if isinstance(v, list):
        return "[" + ", ".join(_toml(w) for w in v) + "]"
    return f'"{v}"'


GEOMETRY = (
    f'geometry = {{ kind = "rectangle", x = [{X_RANGE[0]}, {X_RANGE[1]}], '
    f'y = [{Y_RANGE[0]}, {Y_RANGE[1]}], cells = [4, 2], element = "triangle" }}'
)


def scene_text(fields: dict) -> str:
    """The TOML text of `scenes/manufactured.toml` from `generate()`'s fields."""
    f = {k: _toml(v) for k, v in fields.items()}
    return f"""\
# Manufactured solution (docs/manufactured.md): a BaTiO3 block on a rigid foundation with a known
# exact (u, φ, λ); stick on x < {A_STICK}, slip on x > {A_STICK} along Γ3 = bottom.
# Generated by `python -m problems.manufactured` (sympy, offline); do not edit by hand.
# Units: m, Pa, V, C.

[scene]
title = "Manufactured solution: BaTiO3 block, Tresca contact with stick and slip"
plugin = "piezo_contact"
level = 2

[bodies.block]
material = "{MATERIAL}"
{GEOMETRY}
body_force = {f["body_force"]}
free_charge = {f["free_charge"]}

[[bodies.block.displacement]]
boundary = "top"
value = {f["u"]}

[[bodies.block.potential]]
boundary = "top"
value = {f["phi"]}

[[bodies.block.traction]]
boundary = "left"
value = {f["traction_left"]}

[[bodies.block.traction]]
boundary = "right"
value = {f["traction_right"]}

[[bodies.block.charge]]
boundary = "left"
value = {f["charge_left"]}

[[bodies.block.charge]]
boundary = "right"
value = {f["charge_right"]}

[[bodies.block.charge]]
boundary = "bottom"
value = {f["charge_bottom"]}

[contact]
slave = "block.bottom"
master = "rigid"
g = {f["g"]}

[output]
potential_along = "block.bottom"

[exact]
u = {f["u"]}
grad_u = {f["grad_u"]}
phi = {f["phi"]}
grad_phi = {f["grad_phi"]}
lam = {f["lam"]}
"""


if __name__ == "__main__":
    print(scene_text(generate()), end="")
