"""Exceptions raised by torchpaml: one family, :class:`TorchpamlError`, for every mistake a user's input can cause.
Each message says what was received, what was expected, and the fix.

Each also derives from the built-in exception that code written before the family catches (``ValueError``,
``TypeError``, ``RuntimeError``). The command line reports the family in one line with exit status 2; any other
exception is a bug in torchpaml and is printed with its traceback (:mod:`torchpaml.cli`).
"""

__all__ = ["CompiledPathWarning", "ConfigurationError", "DataError", "DomainError", "PhysicsError", "ResolutionError",
           "SimulationError", "TorchpamlError"]


class TorchpamlError(Exception):
    """Base of the errors a user's input can cause (records, values, names, a model that cannot be simulated)."""


class ConfigurationError(TorchpamlError, ValueError, TypeError):
    """An argument, option or setting that torchpaml cannot use as given: a value outside its range, an unknown name,
    an object of the wrong kind, options that contradict each other."""


class DataError(TorchpamlError, ValueError):
    """Measured or generated data that cannot be used as given (missing columns, NaN, bad time axis...)."""


class SimulationError(TorchpamlError, RuntimeError):
    """A simulation that failed: the solution blew up, or the solver could not advance."""


class ResolutionError(SimulationError):
    """A fitted model whose simulation depends on the RK4 step beyond what substeps can resolve."""


class DomainError(TorchpamlError, ValueError):
    """An input outside the domain a model is defined on (e.g. |u| > alpha for a Chebyshev residual)."""


class PhysicsError(TorchpamlError, ValueError):
    """A user's physics that cannot be simulated as written: a method that raises, a wrong shape, NaN at the start."""


class CompiledPathWarning(UserWarning):
    """The compiled path (C from the physics' closed form) could not be built or loaded on this machine: no C compiler,
    a cache folder that cannot be written, a library that does not load, a compile that fails or hangs. The simulation
    goes on in the torch engine, with the same results, slower; the message says why and how to fix it."""
