"""Exceptions raised by torchpaml. Each message says what was received, what was expected, and the fix."""

__all__ = ["DataError", "DomainError", "PhysicsError", "ResolutionError", "SimulationError"]


class DataError(ValueError):
    """Measured or generated data that cannot be used as given (missing columns, NaN, bad time axis...)."""


class SimulationError(RuntimeError):
    """A simulation that failed: the solution blew up, or the solver could not advance."""


class ResolutionError(SimulationError):
    """A fitted model whose simulation depends on the RK4 step beyond what substeps can resolve."""


class DomainError(ValueError):
    """An input outside the domain a model is defined on (e.g. |u| > alpha for a Chebyshev residual)."""


class PhysicsError(ValueError):
    """A user's physics that cannot be simulated as written: a method that raises, a wrong shape, NaN at the start."""
