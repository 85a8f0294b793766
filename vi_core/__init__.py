"""vi_core: mixed variational inequalities A u + Bᵀλ = f, λ ∈ Λ, Bu − gap ∈ N_Λ(λ).

    from vi_core import MixedVI, Box, Ball, Free, NonNegative, product, solve
"""

from .problem import MixedVI, Residual, Scaling, natural_residual
from .sets import Ball, Box, ConvexSet, Free, NonNegative, Product, product
from .solution import Solution
from .solve import METHODS, solve

__all__ = [
    "METHODS",
    "Ball",
    "Box",
    "ConvexSet",
    "Free",
    "MixedVI",
    "NonNegative",
    "Product",
    "Residual",
    "Scaling",
    "Solution",
    "natural_residual",
    "product",
    "solve",
]
