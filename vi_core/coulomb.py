"""Contact multiplier sets: unilateral contact with Tresca or Coulomb friction.

A `ContactSet` holds k contact nodes in R^dim (dim = 2: one tangent; dim = 3: a tangent plane),
coordinates **node by node**: node j owns dim·j (the normal λ_n) and dim·j + 1 … dim·j + dim − 1
(the tangential λ_t). With z = B u − gap the conditions are, per node,

    λ_n ≥ 0,  z_n ≤ 0,  λ_n z_n = 0                         (unilateral contact)
    |λ_t| ≤ r,  z_t ∈ N_{Ball(r)}(λ_t)                       (friction: stick or slip)

(the mixed VI's sign convention: A u + Bᵀλ = f, so gap − (B u)_n ≥ 0 is the physical gap, and a
slip z_t ≠ 0 points along λ_t). The friction radius r is

    Coulomb(F, dim)                           r = F λ_n           (F ≥ 0 per node)
    UnilateralTresca(g, dim)                  r = g               (everywhere)
    UnilateralTresca(g, dim, contact_only)    r = g where λ_n > 0, r = 0 where λ_n = 0.

With r = F λ_n or g·[λ_n > 0] the set depends on the multiplier itself: a quasi-variational
inequality (`quasi` is True). Such a set is not a fixed convex set, and its `project` is **not a
Euclidean projection** but the combined complementarity map of Hüeber, Stadler and Wohlmuth
(SIAM J. Sci. Comput. 30, 2008), per node with y = λ + c z:

    P(y)_n = max(0, y_n),     P(y)_t = P_{Ball(ρ(y_n))}(y_t),   ρ(y_n) = F·max(0, y_n)
                                                                  (Tresca: g, or g·[y_n > 0])

so that λ − P(λ + c z) = 0 (the natural map every solver and `natural_residual` use) holds
exactly at the solutions: its normal part forces λ_n = max(0, y_n), whence ρ(y_n) = F λ_n. A
semismooth Newton step on this map (vi_core.ssn, unchanged) is the primal–dual active set method
of that paper; `jacobian` returns an element of its generalised derivative, including the
derivative of the radius in y_n (the slip row F ŷ_t of a Coulomb slip node). For a 2D node the
tangential ball is the interval [−ρ, ρ]; in 3D it is the disc.

The conic and homotopy solvers need a fixed convex set and refuse these sets; the fixed point on
Tresca problems (vi_core.tresca_fixed_point) reaches them through `tresca_bound`.

**Uniqueness.** Discrete Coulomb problems have a unique solution only for F small enough (the
bound depends on the mesh and the operator); beyond it the solvers may fail, and they then report
"not converged" rather than an answer (docs/coulomb.md).
"""

from __future__ import annotations

from abc import abstractmethod
from typing import Any

import numpy as np
import scipy.sparse as sp

from .sets import ConvexSet, _per_block, _vector, beyond

OPEN = 1e-10  # `tresca_bound`: λ_n ≤ OPEN · (largest λ_n) counts as apart (rounding)


class ContactSet(ConvexSet):
    """k contact nodes in R^dim, node by node [λ_n, λ_t]; see the module docstring.

    Subclasses give the friction radius ρ(y_n) and its derivative (`radius`) and the Tresca
    bound that freezes the radius at a given λ_n (`tresca_bound`).
    """

    quasi = True

    def __init__(self, k: int, dim: int):
        self.dim = int(dim)
        if self.dim not in (2, 3):
            raise ValueError(f"a contact set needs dim 2 or 3, got {dim}")
        self.k = int(k)
        self.size = self.dim * self.k

    @abstractmethod
    def radius(self, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ρ(y_n), dρ/dy_n), both (k,): the friction radius of the combined map."""

    @abstractmethod
    def tresca_bound(self, lam_n: np.ndarray) -> np.ndarray:
        """The Tresca bound g (k,) that equals the friction radius at the normal multiplier λ_n."""

    def split(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(y_n (k,), y_t (k, dim − 1)) of a vector in this set's coordinates."""
        Y = np.asarray(y, dtype=float).reshape(self.k, self.dim)  # (k, dim)
        return Y[:, 0], Y[:, 1:]

    def project(self, y):
        yn, yt = self.split(y)
        r, _ = self.radius(yn)  # (k,)
        nt = np.linalg.norm(yt, axis=1)  # (k,)
        scale = np.where(nt > r, r / np.where(nt > 0, nt, 1.0), 1.0)  # (k,)
        out = np.empty((self.k, self.dim))
        out[:, 0] = np.maximum(yn, 0.0)
        out[:, 1:] = yt * scale[:, None]
        return out.ravel()

    def jacobian(self, y):
        yn, yt = self.split(y)
        r, dr = self.radius(yn)  # (k,)
        nt = np.linalg.norm(yt, axis=1)  # (k,)
        d, t = self.dim, self.dim - 1
        blocks = np.zeros((self.k, d, d))  # (k, d, d)
        blocks[:, 0, 0] = (yn > 0).astype(float)
        # tangential rows: zero where ρ = 0 (P_t ≡ 0 there), identity while sticking,
        # (ρ/|y_t|)(I − ŷŷᵀ) in y_t and ρ'(y_n) ŷ in y_n while slipping
        out = beyond(nt, r)  # (k,) on the disc's rim counts as sticking (sets.TIE)
        stick = (r > 0) & ~out
        slip = (r > 0) & out
        blocks[stick, 1:, 1:] = np.eye(t)
        if slip.any():
            yh = yt[slip] / nt[slip, None]  # (k_slip, t)
            g = (r[slip] / nt[slip])[:, None, None]  # (k_slip, 1, 1)
            blocks[slip, 1:, 1:] = g * (np.eye(t)[None] - yh[:, :, None] * yh[:, None, :])
            blocks[slip, 1:, 0] = dr[slip, None] * yh
        return sp.block_diag(list(blocks), format="csr") if self.k else sp.csr_matrix((0, 0))

    def _node_scale(self, t: Any) -> np.ndarray:
        return _per_block(t, self.k, self.dim, "a contact set", "node")

    def support(self, z):
        raise NotImplementedError(
            f"{self!r} has no fixed support function: use the fixed point on Tresca problems "
            '(method="fixed_point", inner="conic")'
        )

    def block_sizes(self):
        return np.full(self.k, self.dim, dtype=int)


class Coulomb(ContactSet):
    """Unilateral contact with Coulomb friction |λ_t| ≤ F λ_n at k nodes in R^dim.

    F : (k,) or scalar friction coefficients ≥ 0 (F = 0: frictionless unilateral contact).
    """

    def __init__(self, F: Any, dim: int = 2, k: int | None = None):
        F_a = _vector("friction coefficient F", F, k)
        if (F_a < 0).any() or not np.isfinite(F_a).all():
            j = int(np.flatnonzero((F_a < 0) | ~np.isfinite(F_a))[0])
            raise ValueError(f"friction coefficient F must be finite and ≥ 0; node {j}: {F_a[j]}")
        super().__init__(F_a.size, dim)
        self.F = F_a

    def radius(self, yn):
        return self.F * np.maximum(yn, 0.0), self.F * (yn > 0)

    def tresca_bound(self, lam_n):
        return self.F * np.maximum(np.asarray(lam_n, float), 0.0)

    def scaled(self, t):
        self._node_scale(t)
        return Coulomb(self.F, self.dim)  # λ_t and λ_n scale alike: F is unchanged

    def __repr__(self):
        return f"Coulomb(k={self.k}, dim={self.dim})"


class UnilateralTresca(ContactSet):
    """Unilateral contact with Tresca friction |λ_t| ≤ g at k nodes in R^dim.

    g : (k,) or scalar bounds ≥ 0.
    contact_only : the bound holds only where the bodies touch (λ_n > 0); where they are apart
        λ_t = 0. A quasi-variational set then (`quasi`). With False, |λ_t| ≤ g on every node,
        in contact or not (the classical Tresca problem: a fixed convex set).
    """

    def __init__(self, g: Any, dim: int = 2, contact_only: bool = True, k: int | None = None):
        g_a = _vector("Tresca bound g", g, k)
        if (g_a < 0).any() or not np.isfinite(g_a).all():
            j = int(np.flatnonzero((g_a < 0) | ~np.isfinite(g_a))[0])
            raise ValueError(f"Tresca bound g must be finite and ≥ 0; node {j}: {g_a[j]}")
        super().__init__(g_a.size, dim)
        self.g = g_a
        self.contact_only = bool(contact_only)
        self.quasi = self.contact_only

    def radius(self, yn):
        r = self.g * (yn > 0) if self.contact_only else self.g.copy()
        return r, np.zeros(self.k)

    def tresca_bound(self, lam_n):
        if not self.contact_only:
            return self.g.copy()
        # touching: λ_n above rounding of the largest pressure (a solver's λ_n at a node that is
        # apart is rounding, 1e-15 of the largest, and must not switch the bound on)
        lam_n = np.asarray(lam_n, float)
        return self.g * (lam_n > OPEN * max(float(lam_n.max(initial=0.0)), 0.0))

    def scaled(self, t):
        return UnilateralTresca(self.g / self._node_scale(t), self.dim, self.contact_only)

    def __repr__(self):
        where = "contact_only" if self.contact_only else "everywhere"
        return f"UnilateralTresca(k={self.k}, dim={self.dim}, {where})"
