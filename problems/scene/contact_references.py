"""Closed-form references for contact scenes (independent of the finite element code).

- `hertz_line_contact`: 2D (plane strain) frictionless indentation of a half-plane by a rigid
  cylinder of radius R under the load P per unit length (Johnson, Contact Mechanics, §5.6):
  half-width a = sqrt(4 P R / (π E*)), peak pressure p0 = 2 P / (π a) = sqrt(P E* / (π R)),
  p(x) = p0 sqrt(1 − x²/a²). E* is the plane-strain modulus of the half-plane, E/(1 − ν²) for
  an isotropic one (`isotropic_plane_strain_modulus`), 2/(L⁻¹)_yy of the Barnett–Lothe tensor
  for an anisotropic or (insulating indenter) piezoelectric one, and for a conducting indenter
  on a piezoelectric one the modulus of the (y, φ) Schur complement (`hertz_modulus`).
- `uniaxial_electrical_contact`: a piezoelectric layer 0 < y < H, poled along y, in uniaxial
  strain (rollers on its sides), its top pushed down by δ and held at the potential V, its bottom
  on a rigid foundation with the electrical contact law D·n = k(λ_n)(φ − φ_F) (n = −e_y): every
  field is linear in y and the bottom potential φ0 solves one scalar equation (bracketed root).
- `two_layer_electrical_contact`: the same layer on a second piezoelectric layer instead of the
  foundation, with D·n = k(λ_n)(φ_s − φ_m) across the interface (a bracketed root again).
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
    r_lo, r_hi = (residual(lo), residual(hi)) if lo < hi else (0.0, 0.0)
    if r_lo * r_hi < 0.0:
        phi0 = brentq(residual, lo, hi, xtol=1e-14 * max(abs(lo), abs(hi), 1.0), rtol=1e-15)
    else:  # the root is at an end of the bracket; rounding gave both ends one sign
        phi0 = lo if abs(r_lo) <= abs(r_hi) else hi
    kk = float(k(lam(phi0)))
    return Uniaxial(phi0=phi0, lam_n=lam(phi0), flux=kk * (phi0 - phi_F), k=kk)


@dataclass(frozen=True)
class Layer:
    """A piezoelectric layer in uniaxial strain along its poling axis y: thickness H (m) and
    the constants c33 (Pa), e33 (C/m²), κ33 (F/m)."""

    c33: float
    e33: float
    k33: float
    H: float


@dataclass(frozen=True)
class TwoLayer:
    """The state at the interface of two stacked layers: the slave's and the master's
    potentials there, the pressure, the slave's D·n (n = −e_y), k, the interface's u_y."""

    phi_s: float
    phi_m: float
    lam_n: float
    flux: float
    k: float
    v: float


def two_layer_electrical_contact(
    slave: Layer,
    master: Layer,
    delta: float,
    V: float,
    V_m: float,
    k: Callable[[float], float],
) -> TwoLayer:
    """A slave layer 0 < y < H_s (top pushed down by δ, at potential V) in bilateral contact
    with a master layer −H_m < y < 0 (bottom fixed, at potential V_m) through the electrical
    contact law D·n = k(λ_n)(φ_s − φ_m) (n = −e_y the slave's normal). Every field is linear in
    y in each layer; with v = u_y(0), a = φ_s(0), b = φ_m(0):
        σ_s = c_s(−δ − v)/H_s + e_s(V − a)/H_s,   D_s = e_s(−δ − v)/H_s − κ_s(V − a)/H_s,
        σ_m = c_m v/H_m + e_m(b − V_m)/H_m,       D_m = e_m v/H_m − κ_m(b − V_m)/H_m,
    σ_s = σ_m, D_s = D_m (no charge stays on the interface) and −D_s = k(−σ_s)(a − b). For a
    given k the three are linear (k = ∞: a = b); the pressure solves λ = Λ(k(λ)), a root
    bracketed by Λ(0) and Λ(∞) (k ↦ Λ(k) is a Möbius map, monotone)."""

    def state(kk: float) -> np.ndarray:
        s, m = slave, master
        # rows: σ_s − σ_m = 0, D_s − D_m = 0, law; unknowns x = (v, a, b)
        A = np.array(
            [
                [-s.c33 / s.H - m.c33 / m.H, -s.e33 / s.H, -m.e33 / m.H],
                [-s.e33 / s.H - m.e33 / m.H, s.k33 / s.H, m.k33 / m.H],
                [0.0, 0.0, 0.0],
            ]
        )
        rhs = np.array(
            [
                s.c33 * delta / s.H - s.e33 * V / s.H - m.e33 * V_m / m.H,
                s.e33 * delta / s.H + s.k33 * V / s.H + m.k33 * V_m / m.H,
                0.0,
            ]
        )
        if np.isinf(kk):  # a = b
            A[2] = [0.0, 1.0, -1.0]
        else:  # −D_s − k(a − b) = 0, D_s = e_s(−δ − v)/H_s − κ_s(V − a)/H_s
            A[2] = [s.e33 / s.H, -s.k33 / s.H - kk, kk]
            rhs[2] = -s.e33 * delta / s.H - s.k33 * V / s.H
        return np.linalg.solve(A, rhs)

    def lam(x: np.ndarray) -> float:
        v, a, _ = x
        return -(slave.c33 * (-delta - v) / slave.H + slave.e33 * (V - a) / slave.H)

    l0, l_inf = lam(state(0.0)), lam(state(np.inf))
    lo, hi = min(l0, l_inf), max(l0, l_inf)

    def residual(p: float) -> float:
        return p - lam(state(float(k(p))))

    r_lo, r_hi = (residual(lo), residual(hi)) if lo < hi else (0.0, 0.0)
    if r_lo * r_hi < 0.0:
        p = brentq(residual, lo, hi, xtol=1e-15 * max(abs(lo), abs(hi), 1.0), rtol=1e-15)
    else:  # the root is at an end (r ≤ 0 at lo, ≥ 0 at hi in exact arithmetic): rounding
        p = lo if abs(r_lo) <= abs(r_hi) else hi
    kk = float(k(p))
    v, a, b = state(kk)
    d_s = slave.e33 * (-delta - v) / slave.H - slave.k33 * (V - a) / slave.H
    return TwoLayer(phi_s=a, phi_m=b, lam_n=lam(np.array([v, a, b])), flux=-d_s, k=kk, v=v)


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
    C: np.ndarray,
    e: np.ndarray | None = None,
    kappa: np.ndarray | None = None,
    conducting: bool = False,
) -> float:
    """The plane-strain Hertz modulus E* of a half-plane y < 0 (its surface normal y, the
    poling axis of mixvi's piezoelectric materials) against a rigid frictionless cylinder.

    On the surface, u' = (1/π) L⁻¹ · PV∫t(s)/(s − x) ds for the surface tractions (and, with e
    and κ, the surface charge) t (SL⁻¹ is antisymmetric, and with the mirror symmetry x → −x
    of a material poled along y it does not couple (u_y, φ) with each other: no local term).
    Insulating indenter (default; charge-free surface D·n = 0 everywhere, and the elastic
    case): a normal pressure alone, u_y' = (L⁻¹)_yy/π · PV∫p/(s − x), so E* = 2/(L⁻¹)_yy.
    Conducting indenter (`conducting`; φ constant under it, D·n = 0 outside): the pressure p
    and the surface charge q under the cylinder solve N·H[p, q] = [−x/R, 0] with N the (y, φ)
    block of L⁻¹ and H the finite Hilbert transform; eliminating q, p is Hertz's ellipse with
    2/E* = N_yy − N_yφ²/N_φφ = 1/L_yy (the potential of the indenter only adds a charge
    c/sqrt(a² − x²), which H maps to 0 and p does not see). Derived here from the same surface
    relation (no published 2D formula was found to cite); needs the mirror symmetry (x
    decoupled from (u_y, φ) in L: ValueError otherwise). Isotropic and elastic: E/(1 − ν²)
    either way; BaTiO3: 1.413e11 Pa insulating, 1.235e11 Pa conducting, 1.208e11 Pa elastic."""
    L = barnett_lothe_L(C, e, kappa)
    Li = np.linalg.inv(L)
    if not conducting or e is None:
        return float(2.0 / Li[1, 1])
    coupling = np.abs(L[0, 1:]) / np.sqrt(np.abs(L[0, 0] * np.diag(L)[1:]))  # (2,)
    if coupling.max() > 1e-8:
        raise ValueError(
            f"conducting indenter: L couples u_x with (u_y, φ) ({coupling.max():.1e}); the "
            "closed form needs a material symmetric under x → −x (poled along y)"
        )
    N = Li[1:, 1:]  # (2, 2) the (y, φ) block of L⁻¹
    return float(2.0 / (N[0, 0] - N[0, 1] ** 2 / N[1, 1]))
