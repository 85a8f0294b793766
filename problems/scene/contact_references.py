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
