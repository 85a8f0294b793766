"""3D material tensors in Voigt notation: 6mm piezoelectrics, isotropic and orthotropic elasticity.

Voigt order (xx, yy, zz, yz, xz, xy) = (11, 22, 33, 23, 13, 12), engineering shear strains
γ_ij = 2 ε_ij in the strain vector, plain σ_ij in the stress vector:

    σ = C ε(u) + eᵀ∇φ,   D = e ε(u) − κ∇φ     (the paper's signs, E = −∇φ),

C (6, 6) symmetric, e (3, 6) with rows D_x, D_y, D_z, κ (3, 3) symmetric. Under a rotation R
(x' = R x) the Bond stress matrix M (σ' = M σ) gives C' = M C Mᵀ, e' = R e Mᵀ, κ' = R κ Rᵀ
(strains transform with M⁻ᵀ, so Mᵀ maps rotated strains back).

Crystal class 6mm with the poling axis 3 = z (transversely isotropic about z):
C11 = C22, C12, C13 = C23, C33, C44 = C55, C66 = (C11 − C12)/2; e31 = e32, e33, e15 = e24;
κ11 = κ22, κ33. The poling direction is a parameter: `poled(material, direction)` rotates the
tensors so that axis 3 points along `direction`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

EPS0 = 8.8541878128e-12  # vacuum permittivity, F/m

# Voigt index I -> tensor index pair (i, j)
VOIGT_PAIRS = np.array([[0, 0], [1, 1], [2, 2], [1, 2], [0, 2], [0, 1]])


@dataclass(frozen=True)
class Material3D:
    """A body's 3D constitutive data; `e` and `kappa` are None for a purely elastic body.

    C : (6, 6) Voigt stiffness, e : (3, 6) piezoelectric stress constants, κ : (3, 3)
    permittivity at constant strain, in the conventions of the module docstring.
    """

    name: str
    C: np.ndarray
    e: np.ndarray | None = None
    kappa: np.ndarray | None = None

    @property
    def piezoelectric(self) -> bool:
        return self.e is not None


def bond_matrix(R: np.ndarray) -> np.ndarray:
    """(6, 6) Bond matrix M of the rotation R (3, 3): σ'_Voigt = M σ_Voigt for σ' = R σ Rᵀ."""
    R = np.asarray(R, dtype=float)
    i, j = VOIGT_PAIRS.T  # (6,) each: rows I = (i, j)
    k, l = VOIGT_PAIRS.T  # (6,) each: columns J = (k, l)
    # σ'_ij = Σ_kl R_ik R_jl σ_kl; a shear column J (k ≠ l) collects σ_kl and σ_lk
    M = R[i[:, None], k[None, :]] * R[j[:, None], l[None, :]]  # (6, 6)
    shear = k != l  # (6,)
    M[:, shear] += (R[i[:, None], l[None, :]] * R[j[:, None], k[None, :]])[:, shear]
    return M


def rotate(material: Material3D, R: np.ndarray, name: str | None = None) -> Material3D:
    """The material seen in coordinates x' = R x (R a proper rotation: RᵀR = I, det R = 1)."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-12):
        raise ValueError(f"R must be an orthogonal 3×3 matrix, got {R.tolist()}")
    if np.linalg.det(R) < 0:
        raise ValueError("R must be a proper rotation (det R = +1), got a reflection")
    M = bond_matrix(R)  # (6, 6)
    C = M @ material.C @ M.T  # (6, 6)
    e = None if material.e is None else R @ material.e @ M.T  # (3, 6)
    kappa = None if material.kappa is None else R @ material.kappa @ R.T  # (3, 3)
    return Material3D(name or material.name, 0.5 * (C + C.T), e, kappa)


def rotation_to(direction: Sequence[float]) -> np.ndarray:
    """A proper rotation R (3, 3) with R e_z = d/|d| (the shortest one; about x for d = −e_z)."""
    d = np.asarray(direction, dtype=float)
    if d.shape != (3,) or not np.isfinite(d).all() or np.linalg.norm(d) == 0:
        raise ValueError(f"direction must be a non-zero 3-vector, got {direction!r}")
    d = d / np.linalg.norm(d)
    z = np.array([0.0, 0.0, 1.0])
    c = float(z @ d)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])  # half turn about x
    v = np.cross(z, d)  # (3,) axis · sin θ
    V = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + V + V @ V / (1 + c)  # Rodrigues


def poled(material: Material3D, direction: Sequence[float]) -> Material3D:
    """A 6mm material (given with poling axis 3 = z) poled along `direction` instead."""
    return rotate(material, rotation_to(direction))


def crystal_6mm(
    name: str,
    c11: float,
    c12: float,
    c13: float,
    c33: float,
    c44: float,
    e31: float,
    e33: float,
    e15: float,
    k11: float,
    k33: float,
) -> Material3D:
    """Crystal class 6mm, poled along z; C66 = (c11 − c12)/2 (transverse isotropy)."""
    c66 = 0.5 * (c11 - c12)
    C = np.array(
        [
            [c11, c12, c13, 0, 0, 0],
            [c12, c11, c13, 0, 0, 0],
            [c13, c13, c33, 0, 0, 0],
            [0, 0, 0, c44, 0, 0],
            [0, 0, 0, 0, c44, 0],
            [0, 0, 0, 0, 0, c66],
        ],
        dtype=float,
    )
    e = np.zeros((3, 6))
    e[0, 4] = e15  # D_x ← γ_xz
    e[1, 3] = e15  # D_y ← γ_yz
    e[2, :3] = [e31, e31, e33]  # D_z ← ε_xx, ε_yy, ε_zz
    return Material3D(name, C, e, np.diag([k11, k11, k33]).astype(float))


def isotropic(E: float, nu: float, name: str = "isotropic") -> Material3D:
    """Linear isotropic elasticity (Lamé λ, μ from Young's modulus E and Poisson's ratio ν)."""
    if not (E > 0 and -1 < nu < 0.5):
        raise ValueError(f"need E > 0 and −1 < ν < 1/2, got E={E}, nu={nu}")
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    C = np.zeros((6, 6))
    C[:3, :3] = lam
    C[range(3), range(3)] = lam + 2 * mu
    C[range(3, 6), range(3, 6)] = mu
    return Material3D(name, C)


def orthotropic(
    E: Sequence[float],
    nu: Sequence[float],
    G: Sequence[float],
    name: str = "orthotropic",
) -> Material3D:
    """Orthotropic elasticity in its material axes x, y, z.

    E = (E1, E2, E3); nu = (ν12, ν13, ν23) with ν_ij the contraction along j under stress along
    i (ν_ji = ν_ij E_j / E_i); G = (G23, G13, G12). C is the inverse of the compliance matrix;
    ValueError if it is not positive definite.
    """
    E1, E2, E3 = (float(v) for v in E)
    n12, n13, n23 = (float(v) for v in nu)
    G23, G13, G12 = (float(v) for v in G)
    S = np.zeros((6, 6))  # compliance: ε = S σ
    S[:3, :3] = [
        [1 / E1, -n12 / E1, -n13 / E1],
        [-n12 / E1, 1 / E2, -n23 / E2],
        [-n13 / E1, -n23 / E2, 1 / E3],
    ]
    S[range(3, 6), range(3, 6)] = [1 / G23, 1 / G13, 1 / G12]
    ev = np.linalg.eigvalsh(S)
    if ev.min() <= 0:
        raise ValueError(f"orthotropic constants E={E}, nu={nu}, G={G} are not positive definite")
    C = np.linalg.inv(S)
    return Material3D(name, 0.5 * (C + C.T))


def plane_strain(material: Material3D, plane: str = "xz") -> Material3D:
    """The 2D plane-strain constants in the plane `plane` ("xz", "xy" or "yz").

    With the out-of-plane displacement zero and nothing depending on the out-of-plane coordinate,
    only the in-plane strains (a, b, ab) and field components (a, b) remain: C (3, 3) on
    (aa, bb, ab), e (2, 3), κ (2, 2) — the layout of the 2D assembly (fem.assembly) with its
    x ↦ a, y ↦ b.
    """
    axes = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}
    if plane not in axes:
        raise ValueError(f"unknown plane {plane!r}; expected one of {sorted(axes)}")
    a, b = axes[plane]
    pairs = [tuple(p) for p in VOIGT_PAIRS.tolist()]
    voigt = [pairs.index((a, a)), pairs.index((b, b)), pairs.index((a, b))]
    C = material.C[np.ix_(voigt, voigt)]
    if material.e is None:
        return Material3D(material.name, C)
    return Material3D(
        material.name,
        C,
        material.e[np.ix_([a, b], voigt)],
        material.kappa[np.ix_([a, b], [a, b])],
    )


# Published constants (C in Pa, e in C/m², κ = ε^S in F/m), poling axis 3 = z.
# BaTiO3 (ceramic): the set of docs/design.md §4 (the one the 2D scenes use), as tabulated by
#   M. L. Dunn, M. Taya, Int. J. Solids Struct. 30 (1993) 161–175, after Berlincourt et al.;
#   c12 = c13 = 6.6e10; 6mm symmetry then fixes c66 = (c11 − c12)/2 = 4.2e10.
# PZT-5H and PZT-4: D. A. Berlincourt, D. R. Curran, H. Jaffe, "Piezoelectric and piezomagnetic
#   materials and their function in transducers", Physical Acoustics I-A (1964), as reproduced
#   in B. A. Auld, Acoustic Fields and Waves in Solids, vol. 1, appendix 2 (1973); c66 from
#   6mm symmetry (PZT-4: 3.06e10, PZT-5H: 2.325e10). The values match the sets quoted widely in
#   other codes; they were not re-checked against the printed sources here.
NAMED: dict[str, Material3D] = {
    m.name: m
    for m in (
        crystal_6mm(
            "BaTiO3", 15.0e10, 6.6e10, 6.6e10, 14.6e10, 4.4e10,
            -4.35, 17.5, 11.4, 1115 * EPS0, 1260 * EPS0,
        ),
        crystal_6mm(
            "PZT-5H", 12.6e10, 7.95e10, 8.41e10, 11.7e10, 2.30e10,
            -6.5, 23.3, 17.0, 1700 * EPS0, 1470 * EPS0,
        ),
        crystal_6mm(
            "PZT-4", 13.9e10, 7.78e10, 7.43e10, 11.5e10, 2.56e10,
            -5.2, 15.1, 12.7, 730 * EPS0, 635 * EPS0,
        ),
    )
}  # fmt: skip
