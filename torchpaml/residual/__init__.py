"""Residual models: the orthogonal Chebyshev-Hammerstein model and the MLP baselines."""

from torchpaml.residual.base import AbstractResidual
from torchpaml.residual.chebyshev_hammerstein import ChebyshevHammerstein, chebyshev_t
from torchpaml.residual.mlp import ForceAugmented, MLPForce, MLPResidual

__all__ = ["AbstractResidual", "ChebyshevHammerstein", "chebyshev_t", "MLPResidual", "MLPForce", "ForceAugmented"]
