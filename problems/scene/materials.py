"""Materials of 2D and 3D scenes, from their full 3D tensors (`fem.tensors.Material3D`).

Paper's signs: σ = C ε(u) + eᵀ∇φ, D = e ε(u) − κ∇φ. A 3D scene's material is its Voigt tensors
C (6×6), e (3×6), κ (3×3); a 2D scene's is their plane-strain reduction to the x–y plane
(`plane_strain`): C (3×3) on (xx, yy, xy), e (2×3), κ (2×2), and the out-of-plane stress rows
C_zz, e_zz. Both are derived from one table of crystal constants (CRYSTALS), so that a 3D
scene extruded from a 2D one solves the same problem.

A scene's `material` is a name of CRYSTALS ("BaTiO3"), optionally with the poling direction
(`{ name = "BaTiO3", poling = [0, 0, 1] }`; default the vertical axis: y in 2D, z in 3D) and a
scaled coupling, or a table with `kind` = isotropic (E, ν), anisotropic (C) or piezoelectric
(C, e, κ) whose matrices have the scene's sizes. `MaterialSpec` (2D) and `MaterialSpec3` (3D) are
the same union at the two dimensions (`DIM` of each member); `.material()` is the constitutive
data: a `Material` in 2D, a `Material3D` in 3D.
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

    @property
    def stiffness_scale(self) -> float:
        return float(np.max(np.abs(self.C)))


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


def _elasticity(d: int) -> Any:
    n = VOIGT[d]
    return Annotated[Matrix, _shaped(n, n), _spd(f"elasticity matrix C ({n}×{n} Voigt)")]


def _coupling(d: int) -> Any:
    return Annotated[Matrix, _shaped(d, VOIGT[d])]


def _permittivity(d: int) -> Any:
    return Annotated[Matrix, _shaped(d, d), _spd(f"permittivity κ ({d}×{d})")]


class NamedMaterial(Section):
    """A crystal of CRYSTALS poled along `poling` (default: y in 2D, z in 3D), its piezoelectric
    coupling optionally scaled."""

    DIM: ClassVar[int] = 2
    name: Literal[MATERIAL_NAMES]
    poling: Direction | None = Field(
        None, description="the poling direction [dx, dy, dz] (default: y in 2D, z in 3D)"
    )
    coupling_scale: Annotated[Number, Field(gt=0.0, lt=MAX_COUPLING)] = 1.0

    def material(self) -> Material | Material3D:
        """The constitutive data."""
        m, scale = crystal(self.name, self.poling, self.DIM), self.coupling_scale
        label = self.name if scale == 1.0 else f"{self.name} (coupling ×{scale:g})"
        return _at_dim(Material3D(label, m.C, scale * m.e, m.kappa), self.DIM)


class Isotropic(Section):
    """Linear isotropic elasticity (plane strain in 2D) from Young's modulus E and Poisson's ν."""

    DIM: ClassVar[int] = 2
    kind: Literal["isotropic"]
    E: Annotated[Number, Field(gt=0.0)]
    nu: Annotated[Number, Field(gt=-1.0, lt=0.5)]
    label: Text = "isotropic"

    def material(self) -> Material | Material3D:
        """The constitutive data."""
        return _at_dim(isotropic(self.E, self.nu, self.label), self.DIM)


class Anisotropic(Section):
    """A general elastic material: the Voigt matrix C (3×3 in 2D, 6×6 in 3D; symmetric
    positive definite)."""

    DIM: ClassVar[int] = 2
    kind: Literal["anisotropic"]
    C: _elasticity(2)
    label: Text = "anisotropic"

    def material(self) -> Material | Material3D:
        """The constitutive data."""
        kind = Material if self.DIM == 2 else Material3D
        return kind(self.label, np.array(self.C, dtype=float))


class Piezoelectric(Section):
    """A piezoelectric material: C, the coupling e and the permittivity κ (2D: 3×3, 2×3, 2×2;
    3D: 6×6, 3×6, 3×3)."""

    DIM: ClassVar[int] = 2
    kind: Literal["piezoelectric"]
    C: _elasticity(2)
    e: _coupling(2)
    kappa: _permittivity(2)
    label: Text = "piezoelectric"

    def material(self) -> Material | Material3D:
        """The constitutive data."""
        C, e, k = (np.array(m, dtype=float) for m in (self.C, self.e, self.kappa))
        kind = Material if self.DIM == 2 else Material3D
        return kind(self.label, C, e, k)


class NamedMaterial3(NamedMaterial):
    """A crystal of CRYSTALS in a 3D scene (poled along z unless `poling` says otherwise)."""

    DIM: ClassVar[int] = 3


class Isotropic3(Isotropic):
    """Linear isotropic elasticity in a 3D scene."""

    DIM: ClassVar[int] = 3


class Anisotropic3(Anisotropic):
    """A general elastic material in a 3D scene: C 6×6."""

    DIM: ClassVar[int] = 3
    C: _elasticity(3)


class Piezoelectric3(Piezoelectric):
    """A piezoelectric material in a 3D scene: C 6×6, e 3×6, κ 3×3."""

    DIM: ClassVar[int] = 3
    C: _elasticity(3)
    e: _coupling(3)
    kappa: _permittivity(3)


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


def _spec(*members: type[Section]) -> Any:
    """The material union of one dimension: members named, isotropic, anisotropic, piezoelectric."""
    named, *kinds = members
    union = Annotated[named, Tag("named")]
    for kind, member in zip(KINDS, kinds, strict=True):
        union = union | Annotated[member, Tag(kind)]
    inputs = Literal[MATERIAL_NAMES]
    for member in members:
        inputs = inputs | member
    return Annotated[
        union,
        Discriminator(
            _tag,
            custom_error_type="material",
            custom_error_message="a material name (" + ", ".join(sorted(CRYSTALS)) + ") or a "
            "table with name = NAME (and poling = [dx, dy, dz]) or kind = " + " | ".join(KINDS),
        ),
        BeforeValidator(_named, json_schema_input_type=inputs),
    ]


MaterialSpec = _spec(NamedMaterial, Isotropic, Anisotropic, Piezoelectric)
MaterialSpec3 = _spec(NamedMaterial3, Isotropic3, Anisotropic3, Piezoelectric3)
UNION_TAGS.update(("material", k) for k in ("named", *KINDS))
