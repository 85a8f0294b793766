"""The two bodies of the paper's Section 5 example (docs/design.md §5) as mapped Q1 meshes.

Both bodies share the circle of radius r about `center`; the contact arc Γ3 has opening `angle`
centred at the circle's bottom point, from C_l (angle 3π/2 − angle/2) to C_r (3π/2 + angle/2).
Each body is meshed on its own, so the two sides of Γ3 are non-matching (8 vs 12 segments by
default). Boundary parts have the domain on their left, as `Mesh` requires.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .mapped import arc, coons_block, glue, segment
from .mesh import Mesh


def contact_ends(
    center: Sequence[float], radius: float, angle: float
) -> tuple[np.ndarray, np.ndarray]:
    """The end points (C_l, C_r) of the contact arc, bit-identical to the mesh nodes there."""
    th_l, th_r = 1.5 * np.pi - angle / 2, 1.5 * np.pi + angle / 2
    Cl, Cr = arc(center, radius, th_l, th_r)(np.array([0.0, 1.0]))  # (2, 2)
    return Cl, Cr


def _check_angle(angle: float) -> None:
    if not 0.0 < angle < np.pi:
        raise ValueError(f"contact angle must lie in (0, π), got {angle}")


def half_disc(
    center: Sequence[float] = (0.0, 1.5),
    radius: float = 1.0,
    angle: float = np.pi / 2,
    n_contact: int = 8,
    level: int = 0,
) -> Mesh:
    """The lower half of the disc (the slave body Ω_s), meshed by five Coons blocks.

    Layout: an inner trapezoid under the flat top, surrounded by three ring blocks whose arc
    sides are exactly "free_left" (angles π … θl), "contact" (θl … θr) and "free_right"
    (θr … 2π), θl,r = 3π/2 ∓ angle/2; block corners on the arc are joined to the inner block by
    radial spokes, so no cell has an angle near 180° for moderate openings (≤ 150° up to about
    2 rad; as the opening approaches π the free arcs vanish and the cells beside them flatten:
    170° at 2.8 rad, still convex). Parts: "top" (flat side y = center_y,
    traversed from right to left), "free_left", "contact" (n_contact·2^level segments),
    "free_right". Element sizes are chosen close to the contact arc's r·angle/n.
    """
    _check_angle(angle)
    c = np.asarray(center, dtype=float)
    r = float(radius)
    k = 2**level
    h = r * angle / n_contact  # level-0 element size
    th_l, th_r = 1.5 * np.pi - angle / 2, 1.5 * np.pi + angle / 2
    rho = 0.5 * r  # radius of the inner block's lower corners
    n_c = n_contact * k
    n_f = max(1, round(r * (th_l - np.pi) / h)) * k  # cells along each free arc
    n_r = max(1, round((r - rho) / h)) * k  # cells along the spokes
    pol = lambda rad, th: c + rad * np.array([np.cos(th), np.sin(th)])  # noqa: E731
    A, E = pol(r, np.pi), pol(r, 0.0)  # ends of the flat top (left, right)
    Bl, Br = contact_ends(c, r, angle)  # C_l, C_r: bit-identical to the cradle's
    Ql, Qr = pol(rho, th_l), pol(rho, th_r)  # lower corners of the inner block
    Ul, Ur = c + [-rho, 0.0], c + [rho, 0.0]  # upper corners (on the flat top)
    blocks = [
        coons_block(
            arc(c, r, np.pi, th_l), segment(Bl, Ql), segment(Ql, Ul), segment(Ul, A),
            n_f, n_r, {"bottom": "free_left", "left": "top"},
        ),
        coons_block(
            arc(c, r, th_l, th_r), segment(Br, Qr), segment(Qr, Ql), segment(Ql, Bl),
            n_c, n_r, {"bottom": "contact"},
        ),
        coons_block(
            arc(c, r, th_r, 2 * np.pi), segment(E, Ur), segment(Ur, Qr), segment(Qr, Br),
            n_f, n_r, {"bottom": "free_right", "right": "top"},
        ),
        coons_block(
            segment(Ql, Qr), segment(Qr, Ur), segment(Ur, Ul), segment(Ul, Ql),
            n_c, n_f, {"top": "top"},
        ),
    ]  # fmt: skip
    return glue(blocks, tol=1e-9 * r)


def cradle(
    p2: Sequence[float] = (-1.0, 0.0),
    p3: Sequence[float] = (1.0, 0.0),
    center: Sequence[float] = (0.0, 1.5),
    radius: float = 1.0,
    angle: float = np.pi / 2,
    n_contact: int = 12,
    level: int = 0,
) -> Mesh:
    """The master body Ω_m: P2 → P3 → C_r → (arc) → C_l → P2, one Coons block.

    Parts: "bottom" (P2 → P3), "right" (P3 → C_r), "contact" (the arc from C_r to C_l, i.e.
    traversed clockwise about the circle centre, n_contact·2^level segments), "left" (C_l → P2).
    """
    _check_angle(angle)
    r = float(radius)
    k = 2**level
    Cl, Cr = contact_ends(center, r, angle)
    P2, P3 = np.asarray(p2, dtype=float), np.asarray(p3, dtype=float)
    h = r * angle / n_contact  # level-0 element size along the arc
    height = 0.5 * (np.linalg.norm(Cl - P2) + np.linalg.norm(Cr - P3))
    n_c, n_y = n_contact * k, max(1, round(height / h)) * k
    th_l, th_r = 1.5 * np.pi - angle / 2, 1.5 * np.pi + angle / 2
    return coons_block(
        segment(P2, P3),
        segment(P3, Cr),
        arc(center, r, th_r, th_l),
        segment(Cl, P2),
        n_c,
        n_y,
        {"bottom": "bottom", "right": "right", "top": "contact", "left": "left"},
    )
