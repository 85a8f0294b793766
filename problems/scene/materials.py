"""Materials in 2D plane strain: Voigt C on (xx, yy, xy), piezoelectric e (2×3), permittivity κ.

Paper's signs: σ = C ε(u) + eᵀ∇φ, D = e ε(u) − κ∇φ. Poling axis 3 = y.

A scene's `material` is a name from NAMED ("BaTiO3") or a table with `kind` = isotropic,
anisotropic or piezoelectric (`MaterialSpec`, a union told apart by name/kind); its
`.material()` is the constitutive data.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BeforeValidator, Discriminator, Field, Tag
from pydantic_core import PydanticCustomError

from .fields import Number, Text
from .model import UNION_TAGS, Section

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
MATERIAL_NAMES = tuple(NAMED)
KINDS = ("isotropic", "anisotropic", "piezoelectric")
MAX_COUPLING = 1e3  # coupling_scale: e·1e3 already makes e²/(κ·C) ~ 1e6 (ρ far above 1)


def isotropic_plane_strain(E: float, nu: float) -> np.ndarray:
    """Plane-strain Voigt matrix of a linear isotropic material (Lamé λ, μ from E, ν)."""
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])


Matrix = list[list[Number]]


def _shaped(rows: int, cols: int):
    def check(v: list) -> list:
        if len(v) != rows or any(len(r) != cols for r in v):
            raise PydanticCustomError(
                "matrix", "a {rows}×{cols} matrix of numbers", {"rows": rows, "cols": cols}
            )
        return v

    return AfterValidator(check)


def _spd(what: str):
    def check(v: list) -> list:
        M = np.array(v, dtype=float)
        if not np.allclose(M, M.T, rtol=1e-12, atol=0):
            raise PydanticCustomError("matrix", "a symmetric {what}", {"what": what})
        ev = np.linalg.eigvalsh(M)
        if ev.min() <= 1e-12 * max(abs(ev).max(), 1e-300):
            raise PydanticCustomError(
                "matrix",
                "a positive definite {what} (smallest eigenvalue {ev})",
                {"what": what, "ev": f"{ev.min():.3g}"},
            )
        return v

    return AfterValidator(check)


ElasticityMatrix = Annotated[Matrix, _shaped(3, 3), _spd("elasticity matrix C (3×3 Voigt)")]
CouplingMatrix = Annotated[Matrix, _shaped(2, 3)]
Permittivity = Annotated[Matrix, _shaped(2, 2), _spd("permittivity κ (2×2)")]


class NamedMaterial(Section):
    """A material from the table NAMED, its piezoelectric coupling optionally scaled."""

    name: Literal[MATERIAL_NAMES]
    coupling_scale: Annotated[Number, Field(gt=0.0, lt=MAX_COUPLING)] = 1.0

    def material(self) -> Material:
        """The constitutive data."""
        data, scale = NAMED[self.name], self.coupling_scale
        label = self.name if scale == 1.0 else f"{self.name} (coupling ×{scale:g})"
        C, e, kappa, C_zz, e_zz = (np.array(data[k]) for k in ("C", "e", "kappa", "C_zz", "e_zz"))
        return Material(label, C, scale * e, kappa, C_zz, scale * e_zz)


class Isotropic(Section):
    """Linear isotropic elasticity (plane strain) from Young's modulus E and Poisson's ν."""

    kind: Literal["isotropic"]
    E: Annotated[Number, Field(gt=0.0)]
    nu: Annotated[Number, Field(gt=-1.0, lt=0.5)]
    label: Text = "isotropic"

    def material(self) -> Material:
        """The constitutive data."""
        C = isotropic_plane_strain(self.E, self.nu)
        return Material(self.label, C, C_zz=np.array([C[0, 1], C[0, 1], 0.0]))


class Anisotropic(Section):
    """A general elastic material: the 3×3 Voigt matrix C (symmetric positive definite)."""

    kind: Literal["anisotropic"]
    C: ElasticityMatrix
    label: Text = "anisotropic"

    def material(self) -> Material:
        """The constitutive data."""
        return Material(self.label, np.array(self.C, dtype=float))


class Piezoelectric(Section):
    """A piezoelectric material: C, the coupling e (2×3) and the permittivity κ (2×2)."""

    kind: Literal["piezoelectric"]
    C: ElasticityMatrix
    e: CouplingMatrix
    kappa: Permittivity
    label: Text = "piezoelectric"

    def material(self) -> Material:
        """The constitutive data."""
        C, e, k = (np.array(m, dtype=float) for m in (self.C, self.e, self.kappa))
        return Material(self.label, C, e, k)


def _tag(v: Any) -> str | None:
    if isinstance(v, str):
        return "named"
    if isinstance(v, dict):
        return "named" if "name" in v else v.get("kind") if isinstance(v.get("kind"), str) else None
    if isinstance(v, Section):
        return "named" if isinstance(v, NamedMaterial) else v.kind
    return None


def _named(v: Any) -> Any:
    return {"name": v} if isinstance(v, str) else v


MaterialSpec = Annotated[
    Annotated[NamedMaterial, Tag("named")]
    | Annotated[Isotropic, Tag("isotropic")]
    | Annotated[Anisotropic, Tag("anisotropic")]
    | Annotated[Piezoelectric, Tag("piezoelectric")],
    Discriminator(
        _tag,
        custom_error_type="material",
        custom_error_message="a material name (" + ", ".join(sorted(NAMED)) + ") or a table "
        "with kind = " + " | ".join(KINDS),
    ),
    BeforeValidator(
        _named,
        json_schema_input_type=Literal[MATERIAL_NAMES]
        | NamedMaterial
        | Isotropic
        | Anisotropic
        | Piezoelectric,
    ),
]
UNION_TAGS.update(("material", k) for k in ("named", *KINDS))
