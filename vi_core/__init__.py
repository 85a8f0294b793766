"""vi_core: mixed variational inequalities A u + Bᵀλ = f, λ ∈ Λ, Bu − gap ∈ N_Λ(λ).

    from vi_core import MixedVI, Box, Ball, Free, NonNegative, product, solve, constants
    sol = solve(vi, method="ssn" | "conic" | "homotopy" | "auto", tol=1e-10)

Unilateral contact with friction (`Coulomb`, `UnilateralTresca`: quasi-variational sets,
docs/coulomb.md) takes method="ssn" | "fixed_point" | "auto".

The gallery of test problems and hypothesis strategies live in `vi_core.testing`.
"""

from .constants import Constants, constants, skew_ratio
from .coulomb import ContactSet, Coulomb, UnilateralTresca
from .problem import MixedVI, Residual, Scaling, natural_residual
from .sets import Ball, Box, ConvexSet, Free, NonNegative, Product, product
from .solution import Solution
from .solve import CONTACT_METHODS, METHODS, solve

__all__ = [
    "CONTACT_METHODS",
    "METHODS",
    "Ball",
    "Box",
    "Constants",
    "ContactSet",
    "Coulomb",
    "ConvexSet",
    "Free",
    "MixedVI",
    "NonNegative",
    "Product",
    "Residual",
    "Scaling",
    "Solution",
    "UnilateralTresca",
    "constants",
    "natural_residual",
    "product",
    "skew_ratio",
    "solve",
]
