"""Fitting: stage 1 (physics, prediction error method), stage 2 (residual), the first-order check."""

from torchpaml.fit.first_order import reestimate_shift
from torchpaml.fit.output_error import minimize_output_error
from torchpaml.fit.physics_fit import PhysicsEstimate, estimate_initial_state, fit_physics
from torchpaml.fit.residual_fit import (
    ResidualEstimate,
    fit_chebyshev_hammerstein,
    fit_residual,
)

__all__ = [
    "PhysicsEstimate",
    "estimate_initial_state",
    "ResidualEstimate",
    "fit_chebyshev_hammerstein",
    "fit_physics",
    "fit_residual",
    "minimize_output_error",
    "reestimate_shift",
]
