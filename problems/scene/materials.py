"""Materials of 2D and 3D scenes, from their full 3D tensors (`fem.tensors.Material3D`).

Paper's signs: σ = C ε(u) + eᵀ∇φ, D = e ε(u) − κ∇φ. A 3D scene's material is its Voigt tensors
C (6×6), e (3×6), κ (3×3); a 2D scene's is their plane-strain reduction to the x–y plane
(`plane_strain`): C (3×3) on (xx, yy, xy), e (2×3), κ (2×2), and the out-of-plane stress rows
C_zz, e_zz. Both are derived from one table of crystal constants (CRYSTALS), so that a 3D
scene extruded from a 2D one solves the same problem.

A scene's `material` is a name of CRYSTALS ("BaTiO3"), optionally with the poling direction
(`{ name = "BaTiO3", poling = [0, 0, 1] }`; default the vertical axis: y in 2D, z in 3D) and a
scaled coupling, or a table with `kind` = isotropic (E, ν), anisotropic (C) or piezoelectric
(C, e, κ) whose matrices have the body's sizes (`wrong_size`, checked by the body). One union,
`MaterialSpec`, serves both dimensions: `.material(dim)` is the constitutive data, a `Material`
in 2D, a `Material3D` in 3D.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import AfterValidator, BeforeValidator, Discriminator, Field, Tag
from pydantic_core import PydanticCustomError

from fem.tensors import Material3D, crystal_6mm, isotropic, poled
from fem.tensors import plane_strain as in_plane

from .fields import Direction, Number, Text
from .model import UNION_TAGS, Section

EPS0 = 8.8541878128e-12  # vacuum permittivity, F/m


@dataclass(frozen=True)
class Material:
    """A body's 2D constitutive data; `e` and `kappa` are None for a purely elastic body.

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


def plane_strain(m: Material3D) -> Material:
    """The 2D plane-strain material in the x–y plane of the 3D material `m`: its in-plane
    constants (`fem.tensors.plane_strain`) and the σ_zz rows of its full tensors."""
    p = in_plane(m, "xy")
    inplane = [0, 1, 5]  # Voigt xx, yy, xy
    C_zz = m.C[2, inplane]  # (3,)
    e_zz = None if m.e is None else m.e[:2, 2]  # (2,) D_x, D_y ← ε_zz, i.e. σ_zz ← ∇φ
    return Material(m.name, p.C, p.e, p.kappa, C_zz, e_zz)


# docs/design.md, "Materials": BaTiO3 (one commonly quoted set), Berlincourt's set, and PZT-5H,
# crystal class 6mm poled along axis 3 (`fem.tensors.crystal_6mm`): c11, c12, c13, c33, c44 in
# Pa; e31, e33, e15 in C/m²; κ11, κ33 in F/m.
CRYSTALS: dict[str, tuple[float, ...]] = {
    "BaTiO3": (15.0e10, 6.6e10, 6.6e10, 14.6e10, 4.4e10, -4.35, 17.5, 11.4, 9.87e-9, 1.116e-8),
    "BaTiO3-Berlincourt": (
        16.6e10, 7.7e10, 7.8e10, 16.2e10, 4.3e10, -4.4, 18.6, 11.6, 11.2e-9, 12.6e-9
    ),
    "PZT-5H": (
        12.6e10, 7.95e10, 8.41e10, 11.7e10, 2.30e10, -6.5, 23.3, 17.0, 1700 * EPS0, 1470 * EPS0
    ),
}  # fmt: skip
MATERIAL_NAMES = tuple(CRYSTALS)
KINDS = ("isotropic", "anisotropic", "piezoelectric")
MAX_COUPLING = 1e3  # coupling_scale: e·1e3 already makes e²/(κ·C) ~ 1e6 (ρ far above 1)
VERTICAL = {2: [0.0, 1.0, 0.0], 3: [0.0, 0.0, 1.0]}  # the default poling axis per dimension


def crystal(name: str, poling: list[float] | None = None, dim: int = 3) -> Material3D:
    """The crystal `name` of CRYSTALS poled along `poling` (default VERTICAL[dim])."""
    return poled(crystal_6mm(name, *CRYSTALS[name]), VERTICAL[dim] if poling is None else poling)


def _plane_strain_table(name: str) -> dict[str, list]:
    m = plane_strain(crystal(name, dim=2))
    return {k: getattr(m, k).tolist() for k in ("C", "e", "kappa", "C_zz", "e_zz")}


# the 2D constants of every crystal poled along y (C, e, kappa, C_zz, e_zz as nested lists)
NAMED: dict[str, dict[str, list]] = {name: _plane_strain_table(name) for name in CRYSTALS}


def isotropic_plane_strain(E: float, nu: float) -> np.ndarray:
    """Plane-strain Voigt matrix (3, 3) of a linear isotropic material (Lamé λ, μ from E, ν)."""
    return plane_strain(isotropic(E, nu)).C


def _at_dim(m: Material3D, dim: int) -> Material | Material3D:
    """The constitutive data of a scene of dimension `dim`: `m` itself in 3D, its plane-strain
    reduction in 2D."""
    return m if dim == 3 else plane_strain(m)


Matrix = list[list[Number]]
VOIGT = {2: 3, 3: 6}  # Voigt size per dimension


def _rows(square: bool):
    def check(v: list) -> list:
        if not v or len(v) > 6 or any(len(r) != (len(v) if square else len(v[0])) for r in v):
            kind = "square matrix" if square else "matrix"
            raise PydanticCustomError("matrix", "a {kind} of numbers (6×6 at most)", {"kind": kind})
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


# the shapes by dimension (`MaterialTable.wrong_size`): C d_V × d_V (Voigt), e d × d_V, κ d × d
Elasticity = Annotated[Matrix, _rows(True), _spd("elasticity matrix C (Voigt)")]
Coupling = Annotated[Matrix, _rows(False)]
Permittivity = Annotated[Matrix, _rows(True), _spd("permittivity κ")]
SHAPES = {
    "C": lambda d: (VOIGT[d], VOIGT[d]),
    "e": lambda d: (d, VOIGT[d]),
    "kappa": lambda d: (d, d),
}


class MaterialTable(Section):
    """A scene's material, of either dimension: `material(dim)` is its constitutive data in a
    body of dimension `dim`, `wrong_size(dim)` the first matrix whose shape does not fit it."""

    piezoelectric: ClassVar[bool] = False  # whether it couples a potential (a body's φ)

    def material(self, dim: int) -> Material | Material3D:
        """The constitutive data in a body of dimension `dim`."""
        raise NotImplementedError

    def wrong_size(self, dim: int) -> tuple[str, list, str] | None:
        """(key, value, what is allowed) of the first matrix whose shape does not fit a body
        of dimension `dim`; None if all do."""
        for key, shape in SHAPES.items():
            m = getattr(self, key, None)
            rows, cols = shape(dim)
            if m is not None and (len(m) != rows or len(m[0]) != cols):
                return key, m, f"a {rows}×{cols} matrix of numbers (the body is {dim}D)"
        return None


class NamedMaterial(MaterialTable):
    """A crystal of CRYSTALS poled along `poling` (default: y in 2D, z in 3D), its piezoelectric
    coupling optionally scaled."""

    piezoelectric: ClassVar[bool] = True
    name: Literal[MATERIAL_NAMES]
    poling: Direction | None = Field(
        None, description="the poling direction [dx, dy, dz] (default: y in 2D, z in 3D)"
    )
    coupling_scale: Annotated[Number, Field(gt=0.0, lt=MAX_COUPLING)] = 1.0

    @property
    def label(self) -> str:
        """The name, with the coupling's scale if it is not 1."""
        scale = self.coupling_scale
        return self.name if scale == 1.0 else f"{self.name} (coupling ×{scale:g})"

    def material(self, dim: int) -> Material | Material3D:
        """The constitutive data in a body of dimension `dim`."""
        m = crystal(self.name, self.poling, dim)
        return _at_dim(Material3D(self.label, m.C, self.coupling_scale * m.e, m.kappa), dim)


class Isotropic(MaterialTable):
    """Linear isotropic elasticity (plane strain in 2D) from Young's modulus E and Poisson's ν."""

    kind: Literal["isotropic"]
    E: Annotated[Number, Field(gt=0.0)]
    nu: Annotated[Number, Field(gt=-1.0, lt=0.5)]
    label: Text = "isotropic"

    def material(self, dim: int) -> Material | Material3D:
        """The constitutive data in a body of dimension `dim`."""
        return _at_dim(isotropic(self.E, self.nu, self.label), dim)


class Anisotropic(MaterialTable):
    """A general elastic material: the Voigt matrix C (3×3 in 2D, 6×6 in 3D; symmetric
    positive definite)."""

    kind: Literal["anisotropic"]
    C: Elasticity
    label: Text = "anisotropic"

    def material(self, dim: int) -> Material | Material3D:
        """The constitutive data in a body of dimension `dim`."""
        return (Material if dim == 2 else Material3D)(self.label, np.array(self.C, dtype=float))


class Piezoelectric(MaterialTable):
    """A piezoelectric material: C, the coupling e and the permittivity κ (2D: 3×3, 2×3, 2×2;
    3D: 6×6, 3×6, 3×3)."""

    piezoelectric: ClassVar[bool] = True
    kind: Literal["piezoelectric"]
    C: Elasticity
    e: Coupling
    kappa: Permittivity
    label: Text = "piezoelectric"

    def material(self, dim: int) -> Material | Material3D:
        """The constitutive data in a body of dimension `dim`."""
        C, e, k = (np.array(m, dtype=float) for m in (self.C, self.e, self.kappa))
        return (Material if dim == 2 else Material3D)(self.label, C, e, k)


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


members = (NamedMaterial, Isotropic, Anisotropic, Piezoelectric)
union = Annotated[NamedMaterial, Tag("named")]
for kind, member in zip(KINDS, members[1:], strict=True):
    union = union | Annotated[member, Tag(kind)]
inputs = Literal[MATERIAL_NAMES]
for member in members:
    inputs = inputs | member
MaterialSpec = Annotated[
    union,
    Discriminator(
        _tag,
        custom_error_type="material",
        custom_error_message="a material name (" + ", ".join(sorted(CRYSTALS)) + ") or a "
        "table with name = NAME (and poling = [dx, dy, dz]) or kind = " + " | ".join(KINDS),
    ),
    BeforeValidator(_named, json_schema_input_type=inputs),
]
UNION_TAGS.update(("material", k) for k in ("named", *KINDS))
