"""Fitting: stage 1 (physics, prediction error method), stage 2 (residual), the first-order check."""

from torchpaml.fit.first_order import reestimate_shift
from torchpaml.fit.least_squares import LeastSquaresFit, fit_least_squares
from torchpaml.fit.output_error import minimize_output_error
from torchpaml.fit.physics_fit import PhysicsEstimate, fit_physics
from torchpaml.fit.residual_fit import (
    ResidualEstimate,
    fit_chebyshev_hammerstein,
    fit_residual,
)

__all__ = [
    "LeastSquaresFit",
    "PhysicsEstimate",
    "ResidualEstimate",
    "fit_chebyshev_hammerstein",
    "fit_least_squares",
    "fit_physics",
    "fit_residual",
    "minimize_output_error",
    "reestimate_shift",
]
