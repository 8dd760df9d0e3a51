"""Where each record's simulation starts: the initial-state policy of a fit, a ranking and a diagnosis.

``Rest()`` (the default) starts every record at the physics' rest state; ``Estimate()`` fits each training
record's initial state with the parameters (one unbounded unknown per state) and starts each validation record
from the state that best explains it, the parameters fixed, as MATLAB's ``compare`` does. The strings
``"rest"`` and ``"estimate"`` name them wherever a policy is taken (:func:`as_initial_state`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from torchpaml._errors import ConfigurationError

__all__ = ["Estimate", "InitialState", "Rest", "as_initial_state"]


class InitialState:
    """Base of the initial-state policies (module docstring)."""

    #: Whether the records' initial states are estimated (unknowns of the fits) rather than rest.
    estimated: ClassVar[bool]
    #: The policy's name in configs and on the command line.
    name: ClassVar[str]


@dataclass(frozen=True)
class Rest(InitialState):
    """Every record starts at the physics' rest state (``physics.initial_state``)."""

    estimated: ClassVar[bool] = False
    name: ClassVar[str] = "rest"


@dataclass(frozen=True)
class Estimate(InitialState):
    """Each record's initial state is estimated: with the parameters on the training records, with the parameters
    fixed on the validation records."""

    estimated: ClassVar[bool] = True
    name: ClassVar[str] = "estimate"


def as_initial_state(value: str | InitialState) -> InitialState:
    """The policy ``value`` names: ``"rest"``, ``"estimate"`` or a policy itself."""
    if isinstance(value, InitialState):
        return value
    policies = {policy.name: policy for policy in (Rest(), Estimate())}
    if value not in policies:
        raise ConfigurationError(f"initial_state must be 'rest' or 'estimate' (Rest() or Estimate()), got {value!r}")
    return policies[value]
