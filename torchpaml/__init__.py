"""torchpaml: physics-augmented learning of input-driven dynamical systems, with orthogonal residuals.

Plain ``nn.Module`` physics and residuals, simulators (exact LTI and torchdiffeq), two-stage
fitting, and incompatibility certificates, following Kuang & Lin, "Structural Constraints for
Physics-augmented Learning".
"""

from torchpaml.certificates import Certificate, draw_chebyshev, draw_mlp, incompatibility_certificates
from torchpaml.data import Experiment
from torchpaml.errors import DataError, DomainError, ResolutionError, SimulationError
from torchpaml.fit import (
    PhysicsEstimate,
    ResidualEstimate,
    estimate_initial_state,
    fit_chebyshev_hammerstein,
    fit_physics,
    fit_residual,
    reestimate_shift,
)
from torchpaml.metrics import fit_percent, mismatch, rmse
from torchpaml.parameters import Interval, PhysicalParameter, Positive, Real, register_parameters
from torchpaml.physics import AbstractPhysics, Oscillator, Pendulum, SecondOrderPhysics
from torchpaml.residual import AbstractResidual, ChebyshevHammerstein, ForceAugmented, MLPForce, MLPResidual
from torchpaml.simulate import simulate

__all__ = [
    "AbstractPhysics",
    "AbstractResidual",
    "Certificate",
    "ChebyshevHammerstein",
    "DataError",
    "DomainError",
    "Experiment",
    "ForceAugmented",
    "Interval",
    "MLPForce",
    "MLPResidual",
    "Oscillator",
    "Pendulum",
    "PhysicalParameter",
    "PhysicsEstimate",
    "Positive",
    "Real",
    "ResidualEstimate",
    "ResolutionError",
    "SecondOrderPhysics",
    "SimulationError",
    "draw_chebyshev",
    "draw_mlp",
    "fit_chebyshev_hammerstein",
    "fit_percent",
    "estimate_initial_state",
    "fit_physics",
    "fit_residual",
    "incompatibility_certificates",
    "mismatch",
    "reestimate_shift",
    "register_parameters",
    "rmse",
    "simulate",
]
