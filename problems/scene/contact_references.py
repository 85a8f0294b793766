"""Closed-form references for contact scenes (independent of the finite element code).

- `hertz_line_contact`: 2D (plane strain) frictionless indentation of a half-plane by a rigid
  cylinder of radius R under the load P per unit length (Johnson, Contact Mechanics, §5.6):
  half-width a = sqrt(4 P R / (π E*)), peak pressure p0 = 2 P / (π a) = sqrt(P E* / (π R)),
  p(x) = p0 sqrt(1 − x²/a²). E* is the plane-strain modulus of the half-plane, E/(1 − ν²) for
  an isotropic one (`isotropic_plane_strain_modulus`).
- `uniaxial_electrical_contact`: a piezoelectric layer 0 < y < H, poled along y, in uniaxial
  strain (rollers on its sides), its top pushed down by δ and held at the potential V, its bottom
  on a rigid foundation with the electrical contact law D·n = k(λ_n)(φ − φ_F) (n = −e_y): every
  field is linear in y and the bottom potential φ0 solves one scalar equation (bracketed root).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq


@dataclass(frozen=True)
class Hertz:
    """Half-width a (m), peak pressure p0 (Pa) and the pressure p(x) (Pa) of a line contact."""

    a: float
    p0: float

    def pressure(self, x: np.ndarray) -> np.ndarray:
        """p(x) = p0 sqrt(1 − x²/a²) inside |x| < a, 0 outside."""
        r = 1.0 - (np.asarray(x, dtype=float) / self.a) ** 2
        return self.p0 * np.sqrt(np.maximum(r, 0.0))


def hertz_line_contact(P: float, R: float, E_star: float) -> Hertz:
    """The Hertz line contact of a rigid cylinder (radius R) on a half-plane of plane-strain
    modulus E_star under the load P > 0 per unit length."""
    if not (P > 0 and R > 0 and E_star > 0):
        raise ValueError(f"need P, R, E* > 0, got P={P!r}, R={R!r}, E*={E_star!r}")
    a = float(np.sqrt(4.0 * P * R / (np.pi * E_star)))
    return Hertz(a=a, p0=2.0 * P / (np.pi * a))


def isotropic_plane_strain_modulus(E: float, nu: float) -> float:
    """E* = E / (1 − ν²): the half-plane's modulus against a rigid indenter."""
    return E / (1.0 - nu**2)


@dataclass(frozen=True)
class Uniaxial:
    """The uniaxial electrical contact state: bottom potential, pressure, D·n and k there."""

    phi0: float  # V, φ at y = 0
    lam_n: float  # Pa, contact pressure −σ_yy
    flux: float  # C/m², D·n at y = 0 (n = −e_y)
    k: float  # F/m², k(λ_n)


def uniaxial_electrical_contact(
    c33: float,
    e33: float,
    k33: float,
    H: float,
    delta: float,
    V: float,
    phi_F: float,
    k: Callable[[float], float],
) -> Uniaxial:
    """The layer's bottom state (module docstring). Signs of σ = Cε + eᵀ∇φ, D = eε − κ∇φ:
    σ_yy = −c33 δ/H + e33 (V − φ0)/H, D_y = −e33 δ/H − k33 (V − φ0)/H, λ_n = −σ_yy and
    −D_y = k(λ_n)(φ0 − φ_F). The root lies between φ_F and the insulating φ0 (D_y = 0)."""

    def lam(phi0: float) -> float:
        return c33 * delta / H - e33 * (V - phi0) / H

    def residual(phi0: float) -> float:
        d_y = -e33 * delta / H - k33 * (V - phi0) / H
        return -d_y - k(lam(phi0)) * (phi0 - phi_F)

    phi_ins = V + e33 * delta / k33
    lo, hi = min(phi_F, phi_ins), max(phi_F, phi_ins)
    if residual(lo) == 0.0 or lo == hi:
        phi0 = lo
    elif residual(hi) == 0.0:
        phi0 = hi
    else:
        phi0 = brentq(residual, lo, hi, xtol=1e-14 * max(abs(lo), abs(hi), 1.0), rtol=1e-15)
    kk = float(k(lam(phi0)))
    return Uniaxial(phi0=phi0, lam_n=lam(phi0), flux=kk * (phi0 - phi_F), k=kk)


VOIGT = ((0, 2), (2, 1))  # VOIGT[i][j]: the Voigt index of (i, j) in (xx, yy, xy)


def extended_moduli(
    C: np.ndarray, e: np.ndarray | None = None, kappa: np.ndarray | None = None
) -> np.ndarray:
    """E_iJKl (2, n, n, 2), n = 2 (elastic) or 3 (u_x, u_y, φ), of σ_iJ = E_iJKl u_K,l with
    σ_i3 = D_i (Barnett–Lothe's extension), in mixvi's signs σ = Cε + eᵀ∇φ, D = eε − κ∇φ."""
    n = 2 if e is None else 3
    E = np.zeros((2, n, n, 2))
    for i in range(2):
        for ll in range(2):
            for J in range(2):
                for K in range(2):
                    E[i, J, K, ll] = C[VOIGT[i][J], VOIGT[K][ll]]
                if n == 3:
                    E[i, J, 2, ll] = e[ll, VOIGT[i][J]]  # σ_iJ from φ,l
                    E[i, 2, J, ll] = e[i, VOIGT[J][ll]]  # D_i from u_J,l
            if n == 3:
                E[i, 2, 2, ll] = -kappa[i, ll]
    return E


def barnett_lothe_L(
    C: np.ndarray,
    e: np.ndarray | None = None,
    kappa: np.ndarray | None = None,
    points: int = 256,
) -> np.ndarray:
    """The Barnett–Lothe tensor L (n, n) of the (extended) Stroh formalism for the plane x–y,
    by its integral form L = −(1/π) ∫_0^π (R T⁻¹ Rᵀ − Q)(θ) dθ with Q = n·E·n, R = n·E·m,
    T = m·E·m, n = (cos θ, sin θ), m = (−sin θ, cos θ) (Ting, Anisotropic Elasticity, 1996,
    §7.6; Barnett & Lothe 1975 for the piezoelectric extension). The integrand is smooth and
    π-periodic: the trapezoidal rule on `points` nodes converges geometrically, and degenerate
    (isotropic) materials need no special case. Isotropic plane strain: L = E/(2(1 − ν²)) I."""
    E = extended_moduli(C, e, kappa)
    th = np.pi * np.arange(points) / points  # (points,)
    nv = np.stack([np.cos(th), np.sin(th)], axis=1)  # (points, 2)
    mv = np.stack([-np.sin(th), np.cos(th)], axis=1)  # (points, 2)
    Q = np.einsum("ti,iJKl,tl->tJK", nv, E, nv)  # (points, n, n)
    R = np.einsum("ti,iJKl,tl->tJK", nv, E, mv)
    T = np.einsum("ti,iJKl,tl->tJK", mv, E, mv)
    N3 = R @ np.linalg.solve(T, np.swapaxes(R, 1, 2)) - Q  # (points, n, n)
    L = -N3.mean(axis=0)
    return 0.5 * (L + L.T)


def hertz_modulus(
    C: np.ndarray, e: np.ndarray | None = None, kappa: np.ndarray | None = None
) -> float:
    """The plane-strain Hertz modulus E* = 2 / (L⁻¹)_yy of a half-plane y < 0 (its surface
    normal y, the poling axis of mixvi's piezoelectric materials) against a rigid frictionless
    cylinder: the surface slope is u_y' = (L⁻¹)_yy/π · PV∫p(s)/(s − x) ds under a normal pressure
    alone (SL⁻¹ is antisymmetric, so no local term), the isotropic one with 2/E*. With e and κ
    the surface is charge free (an insulating indenter: D·n = 0 on the whole surface) and L the
    extended tensor; the conducting indenter (φ prescribed under it) is not covered."""
    Li = np.linalg.inv(barnett_lothe_L(C, e, kappa))
    return float(2.0 / Li[1, 1])
