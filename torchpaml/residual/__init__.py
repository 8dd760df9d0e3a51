"""Residual models: the orthogonal Chebyshev-Hammerstein model, the MLP baselines, and their hybrids."""

from torchpaml.residual.base import AbstractResidual
from torchpaml.residual.chebyshev_hammerstein import ChebyshevHammerstein, chebyshev_t
from torchpaml.residual.hybrid import Hybrid
from torchpaml.residual.mlp import ForceAugmented, MLPForce, MLPResidual

__all__ = [
    "AbstractResidual",
    "ChebyshevHammerstein",
    "chebyshev_t",
    "Hybrid",
    "MLPResidual",
    "MLPForce",
    "ForceAugmented",
]
