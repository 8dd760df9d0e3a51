"""Fitting: stage 1 (physics, prediction error method), stage 2 (residual), the first-order check, and the
neural force and sparse regression of discovery."""

from torchpaml._fit.first_order import reestimate_shift
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._fit.initial_state import Estimate, InitialState, Rest
from torchpaml._fit.neural_force import NeuralForceFit, fit_neural_force
from torchpaml._fit.physics_fit import PhysicsEstimate, estimate_initial_state, fit_physics
from torchpaml._fit.sparse_regression import SparseRegression, stlsq
from torchpaml._fit.residual_fit import (
    ResidualEstimate,
    fit_chebyshev_hammerstein,
    fit_residual,
)

__all__ = [
    "FittedModel",
    "Estimate",
    "InitialState",
    "NeuralForceFit",
    "Rest",
    "PhysicsEstimate",
    "estimate_initial_state",
    "ResidualEstimate",
    "fit_chebyshev_hammerstein",
    "fit_neural_force",
    "fit_physics",
    "fit_residual",
    "reestimate_shift",
    "SparseRegression",
    "stlsq",
]
