"""Materials in 2D plane strain: Voigt C on (xx, yy, xy), piezoelectric e (2×3), permittivity κ.

Paper's signs: σ = C ε(u) + eᵀ∇φ, D = e ε(u) − κ∇φ. Poling axis 3 = y.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from problems.errors import SceneError

from .reader import MAX_MAGNITUDE

EPS0 = 8.8541878128e-12  # vacuum permittivity, F/m


@dataclass(frozen=True)
class Material:
    """A body's constitutive data; `e` and `kappa` are None for a purely elastic body.

    The out-of-plane stress of plane strain (ε_zz = 0), σ_zz = C_zz·ε + e_zz·∇φ, needs
    constants the in-plane problem does not: C_zz (3,) = (c12, c13, 0) for a crystal poled
    along y (z is crystal axis 2), (λ, λ, 0) for an isotropic material, and e_zz (2,) =
    (0, e31). None where the scene's material table does not give them.
    """

    name: str
    C: np.ndarray  # (3, 3)
    e: np.ndarray | None = None  # (2, 3)
    kappa: np.ndarray | None = None  # (2, 2)
    C_zz: np.ndarray | None = None  # (3,) σ_zz row on (ε_xx, ε_yy, γ_xy)
    e_zz: np.ndarray | None = None  # (2,) σ_zz row on ∇φ

    @property
    def piezoelectric(self) -> bool:
        return self.e is not None

    @property
    def stiffness_scale(self) -> float:
        return float(np.max(np.abs(self.C)))


def _piezo(c11, c12, c13, c33, c44, e31, e33, e15, k11, k33) -> dict:
    return {
        "C": [[c11, c13, 0.0], [c13, c33, 0.0], [0.0, 0.0, c44]],
        "C_zz": [c12, c13, 0.0],
        "e_zz": [0.0, e31],
        "e": [[0.0, 0.0, e15], [e31, e33, 0.0]],
        "kappa": [[k11, 0.0], [0.0, k33]],
    }


# docs/design.md, "Materials": BaTiO3 (one commonly quoted set), Berlincourt's set, and PZT-5H
# (c11, c12, c13, c33, c44 in Pa; e31, e33, e15 in C/m²; κ11, κ33 in F/m).
NAMED: dict[str, dict] = {
    "BaTiO3": _piezo(
        15.0e10, 6.6e10, 6.6e10, 14.6e10, 4.4e10, -4.35, 17.5, 11.4, 9.87e-9, 1.116e-8
    ),
    "BaTiO3-Berlincourt": _piezo(
        16.6e10, 7.7e10, 7.8e10, 16.2e10, 4.3e10, -4.4, 18.6, 11.6, 11.2e-9, 12.6e-9
    ),
    "PZT-5H": _piezo(
        12.6e10, 7.95e10, 8.41e10, 11.7e10, 2.30e10, -6.5, 23.3, 17.0, 1700 * EPS0, 1470 * EPS0
    ),
}
KINDS = ("isotropic", "anisotropic", "piezoelectric")
MAX_COUPLING = 1e3  # coupling_scale: e·1e3 already makes e²/(κ·C) ~ 1e6 (ρ far above 1)


def isotropic_plane_strain(E: float, nu: float) -> np.ndarray:
    """Plane-strain Voigt matrix of a linear isotropic material (Lamé λ, μ from E, ν)."""
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])


def _matrix(key: str, value: Any, shape: tuple[int, int]) -> np.ndarray:
    rows = value if isinstance(value, list) else []
    if any(isinstance(x, bool | str) for r in rows if isinstance(r, list) for x in r):
        raise SceneError(key, value, f"a {shape[0]}×{shape[1]} matrix of numbers")
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise SceneError(key, value, f"a {shape[0]}×{shape[1]} matrix of numbers") from None
    if arr.shape != shape:
        raise SceneError(key, value, f"a {shape[0]}×{shape[1]} matrix of numbers")
    if not (np.isfinite(arr).all() and (np.abs(arr) <= MAX_MAGNITUDE).all()):
        raise SceneError(key, value, f"finite numbers of size ≤ {MAX_MAGNITUDE:g}")
    return arr


def _spd(key: str, M: np.ndarray, what: str) -> None:
    if not np.allclose(M, M.T, rtol=1e-12, atol=0):
        raise SceneError(key, M.tolist(), f"a symmetric {what}")
    ev = np.linalg.eigvalsh(M)
    if ev.min() <= 1e-12 * max(abs(ev).max(), 1e-300):
        raise SceneError(
            key, M.tolist(), f"a positive definite {what} (smallest eigenvalue {ev.min():.3g})"
        )


def _number(key: str, value: Any, lo: float | None = None, hi: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SceneError(key, value, "a number")
    v = float(value)
    if not (np.isfinite(v) and abs(v) <= MAX_MAGNITUDE):
        raise SceneError(key, value, f"a finite number of size ≤ {MAX_MAGNITUDE:g}")
    if (lo is not None and v <= lo) or (hi is not None and v >= hi):
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        raise SceneError(key, value, f"a number in the open interval ({lo_s}, {hi_s})")
    return v


def material_from_scene(key: str, spec: Any) -> Material:
    """Build a Material from a scene value: a name ("BaTiO3") or a table (see README)."""
    if isinstance(spec, str):
        spec = {"name": spec}
    if not isinstance(spec, dict):
        raise SceneError(key, spec, "a material name or a table")
    if "name" in spec:
        name = spec["name"]
        if name not in NAMED:
            raise SceneError(f"{key}.name", name, "one of " + ", ".join(sorted(NAMED)))
        extra = set(spec) - {"name", "coupling_scale"}
        if extra:
            k = sorted(extra)[0]
            raise SceneError(f"{key}.{k}", spec[k], "allowed keys: name, coupling_scale")
        data = NAMED[name]
        scale = _number(
            f"{key}.coupling_scale", spec.get("coupling_scale", 1.0), lo=0.0, hi=MAX_COUPLING
        )
        label = name if scale == 1.0 else f"{name} (coupling ×{scale:g})"
        return Material(
            label,
            np.array(data["C"]),
            scale * np.array(data["e"]),
            np.array(data["kappa"]),
            np.array(data["C_zz"]),
            scale * np.array(data["e_zz"]),
        )
    kind = spec.get("kind")
    if kind not in KINDS:
        raise SceneError(f"{key}.kind", kind, "one of " + ", ".join(KINDS) + " (or give a name)")
    allowed = {
        "isotropic": {"kind", "E", "nu", "label"},
        "anisotropic": {"kind", "C", "label"},
        "piezoelectric": {"kind", "C", "e", "kappa", "label"},
    }[kind]
    extra = set(spec) - allowed
    if extra:
        k = sorted(extra)[0]
        raise SceneError(f"{key}.{k}", spec[k], f"allowed keys: {', '.join(sorted(allowed))}")
    for req in sorted(allowed - {"label"}):
        if req not in spec:
            raise SceneError(f"{key}.{req}", None, f"required for a {kind} material")
    label = spec.get("label", kind)
    if not isinstance(label, str):
        raise SceneError(f"{key}.label", label, "a string (the material's name in outputs)")
    if kind == "isotropic":
        E = _number(f"{key}.E", spec["E"], lo=0.0)
        nu = _number(f"{key}.nu", spec["nu"], lo=-1.0, hi=0.5)
        C = isotropic_plane_strain(E, nu)
        return Material(label, C, C_zz=np.array([C[0, 1], C[0, 1], 0.0]))
    C = _matrix(f"{key}.C", spec["C"], (3, 3))
    _spd(f"{key}.C", C, "elasticity matrix C (3×3 Voigt)")
    if kind == "anisotropic":
        return Material(label, C)
    e = _matrix(f"{key}.e", spec["e"], (2, 3))
    kappa = _matrix(f"{key}.kappa", spec["kappa"], (2, 2))
    _spd(f"{key}.kappa", kappa, "permittivity κ (2×2)")
    return Material(label, C, e, kappa)
