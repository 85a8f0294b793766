"""Closed convex multiplier sets Λ and their products.

Every set knows its projection P_Λ, an element of the generalised (Clarke) Jacobian of P_Λ
(used by semismooth Newton), membership, and its support function σ_Λ as a cvxpy expression
(used by the conic path). Sets scale by a positive diagonal (used by equilibration).

A `Ball(radius, dim)` block of k balls owns dim·k consecutive coordinates, ball by ball.

Contact sets whose friction bound depends on the multiplier itself (Coulomb) live in
`vi_core.coulomb`; they set `quasi = True` (a quasi-variational inequality: no fixed convex set,
no support function).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp


def _per_block(t: Any, k: int, dim: int, what: str, block: str) -> np.ndarray:
    """(k,) the scaling t (k·dim,) of `what`'s k blocks of dim coordinates, which must be
    uniform within each `block` (ValueError otherwise)."""
    t = _vector("scaling", t, k * dim).reshape(k, dim)
    if not np.allclose(t, t[:, :1], rtol=1e-12, atol=0):
        raise ValueError(f"{what} can only be scaled uniformly within each {block}")
    return t[:, 0]


def _vector(name: str, value: Any, size: int | None = None) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a scalar or a 1-D array, got shape {arr.shape}")
    if size is not None and arr.size == 1 and size != 1:
        arr = np.full(size, arr[0])
    if size is not None and arr.size != size:
        raise ValueError(f"{name} has {arr.size} entries, expected {size}")
    if np.isnan(arr).any():
        raise ValueError(f"{name} contains NaN")
    return arr


class ConvexSet(ABC):
    """A closed convex set Λ ⊂ R^size (or, with `quasi`, a set depending on λ: vi_core.coulomb)."""

    size: int
    quasi: bool = False  # True: Λ = Λ(λ), `project` is a combined complementarity map

    @abstractmethod
    def project(self, y: np.ndarray) -> np.ndarray:
        """Euclidean projection P_Λ(y)."""

    @abstractmethod
    def jacobian(self, y: np.ndarray) -> sp.csr_matrix:
        """An element of the generalised Jacobian ∂P_Λ(y) (size × size, block diagonal)."""

    @abstractmethod
    def scaled(self, t: np.ndarray) -> ConvexSet:
        """The set {λ / t : λ ∈ Λ} for a positive vector t (uniform within a ball)."""

    @abstractmethod
    def support(self, z: Any) -> Any:
        """σ_Λ(z) = sup_{λ∈Λ} λᵀz as a convex cvxpy expression of the cvxpy vector z."""

    def contains(self, lam: np.ndarray, tol: float = 0.0) -> bool:
        """Whether ‖λ − P_Λ(λ)‖_∞ ≤ tol."""
        lam = np.asarray(lam, dtype=float)
        return bool(np.max(np.abs(lam - self.project(lam)), initial=0.0) <= tol)

    def blocks(self) -> list[ConvexSet]:
        """The elementary blocks of this set, in coordinate order."""
        return [self]

    def block_sizes(self) -> np.ndarray:
        """Sizes of the coupling blocks of ∂P_Λ (1 per coordinate except balls)."""
        return np.ones(self.size, dtype=int)


class _Cone(ConvexSet):
    """A cone of R^k given by its size alone, the same after scaling; its support function (0
    on the polar cone, +∞ elsewhere) is expressed by the caller as a constraint."""

    def __init__(self, k: int):
        self.size = int(k)
        if self.size < 0:
            raise ValueError(f"{type(self).__name__}(k) needs k ≥ 0, got {k}")

    def scaled(self, t):
        return type(self)(self.size)

    def support(self, z):
        return None

    def __repr__(self):
        return f"{type(self).__name__}({self.size})"


class Free(_Cone):
    """Λ = R^k: an equality constraint B u = gap (σ = 0 on {z = 0})."""

    def project(self, y):
        return np.array(y, dtype=float, copy=True)

    def jacobian(self, y):
        return sp.identity(self.size, format="csr")


class NonNegative(_Cone):
    """Λ = {λ ≥ 0}: a unilateral constraint B u ≤ gap, complementarity with λ (σ = 0 on
    {z ≤ 0})."""

    def project(self, y):
        return np.maximum(np.asarray(y, dtype=float), 0.0)

    def jacobian(self, y):
        return sp.diags((np.asarray(y) > 0).astype(float), format="csr")


class Box(ConvexSet):
    """Λ = {lo ≤ λ ≤ hi} coordinatewise (e.g. Box(−g, g): 2D Tresca friction)."""

    def __init__(self, lo: Any, hi: Any, size: int | None = None):
        lo_a = np.atleast_1d(np.asarray(lo, dtype=float))
        hi_a = np.atleast_1d(np.asarray(hi, dtype=float))
        n = size if size is not None else max(lo_a.size, hi_a.size)
        self.lo = _vector("Box lower bound", lo_a, n)
        self.hi = _vector("Box upper bound", hi_a, n)
        bad = np.flatnonzero(self.lo > self.hi)
        if bad.size:
            i = bad[0]
            raise ValueError(
                f"Box needs lo ≤ hi; coordinate {i} has lo = {self.lo[i]!r} > hi = {self.hi[i]!r}"
            )
        self.size = n

    def project(self, y):
        return np.clip(np.asarray(y, dtype=float), self.lo, self.hi)

    def jacobian(self, y):
        y = np.asarray(y)
        inside = (y > self.lo) & (y < self.hi)
        return sp.diags(inside.astype(float), format="csr")

    def scaled(self, t):
        t = _vector("scaling", t, self.size)
        return Box(self.lo / t, self.hi / t)

    def support(self, z):
        import cvxpy as cp

        # σ(z) = Σ max(lo_i z_i, hi_i z_i); finite bounds are required here
        if not (np.isfinite(self.lo).all() and np.isfinite(self.hi).all()):
            raise ValueError("the conic path needs finite Box bounds; use Free/NonNegative blocks")
        return cp.sum(cp.maximum(cp.multiply(self.lo, z), cp.multiply(self.hi, z)))

    def __repr__(self):
        return f"Box(size={self.size})"


# A point whose norm is within this relative band of the radius is on the sphere: its
# side there is decided by rounding alone (a load step warm-started at the last step's solution
# puts every slipping node at |y_t| = ρ to ±1e-14), and two engines that agree to rounding
# (serial splu, PETSc MUMPS on 2 ranks) would then take other generalised derivatives and other
# Newton paths to the same answer. The band makes the choice a rule: on the sphere counts as
# inside (the identity block), as exact equality always did.
TIE = 1e-12


def beyond(norm: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Where a norm lies outside its ball by more than rounding (norm > radius·(1 + TIE));
    `jacobian`s pick the derivative of the projection by it (`project` stays exact)."""
    return norm > radius * (1.0 + TIE)


class Ball(ConvexSet):
    """k Euclidean balls of radius r_j in R^dim (e.g. 3D Tresca friction discs).

    Coordinates are ordered ball by ball: ball j owns coordinates dim·j … dim·j + dim − 1.
    """

    def __init__(self, radius: Any, dim: int = 2):
        self.dim = int(dim)
        if self.dim < 1:
            raise ValueError(f"Ball dim must be ≥ 1, got {dim}")
        self.radius = _vector("Ball radius", radius)
        if (self.radius < 0).any():
            j = int(np.flatnonzero(self.radius < 0)[0])
            raise ValueError(f"Ball radius must be ≥ 0; ball {j} has radius {self.radius[j]!r}")
        self.k = self.radius.size
        self.size = self.dim * self.k

    def _split(self, y):
        Y = np.asarray(y, dtype=float).reshape(self.k, self.dim)  # (k, dim)
        norm = np.linalg.norm(Y, axis=1)  # (k,)
        return Y, norm

    def project(self, y):
        Y, norm = self._split(y)
        scale = np.ones(self.k)
        out = norm > self.radius
        scale[out] = self.radius[out] / norm[out]
        return (Y * scale[:, None]).ravel()

    def jacobian(self, y):
        Y, norm = self._split(y)
        d = self.dim
        blocks = np.broadcast_to(np.eye(d), (self.k, d, d)).copy()  # (k, d, d)
        out = beyond(norm, self.radius)
        if out.any():
            yh = Y[out] / norm[out, None]  # (k_out, d)
            g = (self.radius[out] / norm[out])[:, None, None]  # (k_out, 1, 1)
            blocks[out] = g * (np.eye(d)[None] - yh[:, :, None] * yh[:, None, :])
        return sp.block_diag(list(blocks), format="csr") if self.k else sp.csr_matrix((0, 0))

    def scaled(self, t):
        return Ball(self.radius / _per_block(t, self.k, self.dim, "a Ball", "ball"), self.dim)

    def support(self, z):
        import cvxpy as cp

        Z = cp.reshape(z, (self.k, self.dim), order="C")
        return cp.sum(cp.multiply(self.radius, cp.norm(Z, 2, axis=1)))

    def block_sizes(self):
        return np.full(self.k, self.dim, dtype=int)

    def __repr__(self):
        return f"Ball(k={self.k}, dim={self.dim})"


class Product(ConvexSet):
    """Cartesian product of sets; coordinates are the blocks' coordinates in order."""

    def __init__(self, sets: Sequence[ConvexSet]):
        flat: list[ConvexSet] = []
        for s in sets:
            if not isinstance(s, ConvexSet):
                raise TypeError(f"product() takes ConvexSet blocks, got {type(s).__name__}")
            flat.extend(s.blocks())
        self._blocks = [b for b in flat if b.size > 0]
        self.offsets = np.cumsum([0] + [b.size for b in self._blocks])
        self.size = int(self.offsets[-1])

    def blocks(self):
        return list(self._blocks)

    @property
    def quasi(self) -> bool:
        """Whether some block depends on λ itself (a quasi-variational inequality)."""
        return any(b.quasi for b in self._blocks)

    def slices(self) -> list[slice]:
        """The coordinate range of each block."""
        return [slice(a, b) for a, b in zip(self.offsets[:-1], self.offsets[1:], strict=True)]

    def project(self, y):
        y = np.asarray(y, dtype=float)
        out = np.empty_like(y)
        for b, s in zip(self._blocks, self.slices(), strict=True):
            out[s] = b.project(y[s])
        return out

    def jacobian(self, y):
        mats = [b.jacobian(y[s]) for b, s in zip(self._blocks, self.slices(), strict=True)]
        return sp.block_diag(mats, format="csr") if mats else sp.csr_matrix((0, 0))

    def scaled(self, t):
        t = _vector("scaling", t, self.size)
        return Product([b.scaled(t[s]) for b, s in zip(self._blocks, self.slices(), strict=True)])

    def support(self, z):
        raise NotImplementedError("the conic path handles product blocks one by one")

    def block_sizes(self):
        parts = [b.block_sizes() for b in self._blocks]
        return np.concatenate(parts) if parts else np.zeros(0, dtype=int)

    def __repr__(self):
        return "product(" + ", ".join(map(repr, self._blocks)) + ")"


def product(*sets: ConvexSet) -> Product:
    """Λ = Λ_1 × Λ_2 × …; rows of B follow the blocks in this order."""
    return Product(sets)


def as_product(Lambda: ConvexSet) -> Product:
    """Wrap any set as a Product (a no-op for products)."""
    return Lambda if isinstance(Lambda, Product) else Product([Lambda])
