"""Residual models: the orthogonal Chebyshev-Hammerstein model, the MLP baselines, and their hybrids."""

from torchpaml._residual.base import AbstractResidual
from torchpaml._residual.chebyshev_hammerstein import ChebyshevHammerstein, chebyshev_t
from torchpaml._residual.hybrid import Hybrid
from torchpaml._residual.mlp import ForceAugmented, MLPForce, MLPResidual

__all__ = [
    "AbstractResidual",
    "ChebyshevHammerstein",
    "chebyshev_t",
    "Hybrid",
    "MLPResidual",
    "MLPForce",
    "ForceAugmented",
]
