"""Where each record's simulation starts: the initial-state policy of a fit, a ranking and a diagnosis.

``Rest()`` (the default) starts every record at the physics' rest state; ``Estimate()`` fits each training
record's initial state with the parameters (one unbounded unknown per state) and starts each validation record
from the state that best explains its start window, the parameters fixed: its first :data:`START_WINDOW` of the
samples, at least :data:`MIN_START_SAMPLES` (:func:`start_window`), as the official benchmarks' init windows do. The
record is then scored after that window (:meth:`InitialState.scored_from`), on samples the estimate did not see: an
estimate on the whole record would let a model with more states (an effect with its own) fit its validation
record through them. The strings
``"rest"`` and ``"estimate"`` name them wherever a policy is taken (:func:`as_initial_state`; deprecated, they go
in the next release).

A policy is an object with methods, not a flag: each fit, ranking and discovery asks it for the initial-state
unknowns, their labels, the states a point of the fit gives, the states a refit carries over, the validation
records' starts and the free responses that a regression needs.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch

from torchpaml._data import Record
from torchpaml._data.simulation import record_jacobian, simulate_record
from torchpaml._errors import ConfigurationError, DataError
from torchpaml._physics.base import AbstractPhysics, complete_state
from torchpaml._simulate.solvers import Solver

__all__ = ["Estimate", "InitialState", "MIN_START_SAMPLES", "Rest", "START_WINDOW", "as_initial_state",
           "policy_named", "start_window"]

#: The share of a validation record, at its start, on which ``Estimate()`` estimates its initial state.
START_WINDOW = 0.1
#: The fewest samples that window holds.
MIN_START_SAMPLES = 20


def start_window(samples: int, name: str = "the record") -> int:
    """How many of a record's ``samples`` its start window holds: :data:`START_WINDOW` of them, at least
    :data:`MIN_START_SAMPLES`. A record is scored after its window, on at least as many samples as the window's least:
    one of fewer than ``2 * MIN_START_SAMPLES`` samples is refused (a :class:`~torchpaml.DataError` that names
    ``name``), never scored on the few samples left."""
    if samples < 2 * MIN_START_SAMPLES:
        raise DataError(f"{name} has {samples} samples: with initial_state Estimate() a validation record's initial "
                        f"state is estimated on a start window of at least {MIN_START_SAMPLES} samples and the record "
                        f"is scored after it, so it needs at least {2 * MIN_START_SAMPLES}; give a longer record, or "
                        "initial_state rest (Rest())")
    return max(MIN_START_SAMPLES, int(START_WINDOW * samples))


class InitialState:
    """Base of the initial-state policies (module docstring)."""

    #: Whether the records' initial states are estimated (unknowns of the fits) rather than rest (informative: the
    #: library asks the policy's methods).
    estimated: ClassVar[bool]
    #: The policy's name in configs and on the command line.
    name: ClassVar[str]

    def unknowns(self, physics: AbstractPhysics, records: Sequence[Record]) -> int:
        """How many initial-state unknowns a fit of ``physics`` on ``records`` has."""
        raise NotImplementedError

    def labels(self, physics: AbstractPhysics, records: Sequence[Record]) -> list[str]:
        """The unknowns' names, ``x0[record].state``, in the fit's order."""
        raise NotImplementedError

    def guesses(self, physics: AbstractPhysics, records: Sequence[Record],
                start_states: Sequence[torch.Tensor] | None) -> list[np.ndarray]:
        """The unknowns' starting values, one array (n_state,) per record."""
        raise NotImplementedError

    def states(self, physics: AbstractPhysics, records: Sequence[Record],
               values: np.ndarray) -> list[torch.Tensor | None]:
        """Each record's initial state (1, n_state) from the unknowns' ``values``; ``None``: rest."""
        raise NotImplementedError

    def carried(self, states: list[torch.Tensor] | None) -> list[torch.Tensor] | None:
        """The training records' initial states a refit of a model built on a fit starts from (the fit's ``states``,
        or ``None``: rest)."""
        raise NotImplementedError

    def validation_starts(self, records: Sequence[Record],
                          estimate: Callable[[Record], torch.Tensor]) -> list[torch.Tensor | None]:
        """Each validation record's initial state, ``estimate(window)`` being the state that best explains the
        record ``window`` (its start window, :meth:`scored_from`'s samples)."""
        raise NotImplementedError

    def scored_from(self, record: Record) -> int:
        """The first sample of ``record`` a validation mismatch is scored on: after the samples its start was
        estimated on."""
        raise NotImplementedError

    def free_response(self, physics: AbstractPhysics, record: Record, x0: torch.Tensor | None,
                      solver: Solver) -> tuple[torch.Tensor, torch.Tensor]:
        """The output on ``record`` from ``x0``, (1, time, n_output), and its derivatives in the initial-state
        unknowns (time, n_output, k), k = 0 at rest."""
        raise NotImplementedError


@dataclass(frozen=True)
class Rest(InitialState):
    """Every record starts at the physics' rest state (``physics.initial_state``)."""

    estimated: ClassVar[bool] = False
    name: ClassVar[str] = "rest"

    def unknowns(self, physics, records):
        return 0

    def labels(self, physics, records):
        return []

    def guesses(self, physics, records, start_states):
        if start_states is not None:
            raise ConfigurationError(f"start_states needs initial_state=Estimate(); got them with {self!r}")
        return []

    def states(self, physics, records, values):
        return [None] * len(records)

    def carried(self, states):
        return None

    def validation_starts(self, records, estimate):
        return [None] * len(records)

    def scored_from(self, record):
        return 0

    def free_response(self, physics, record, x0, solver):
        y = simulate_record(physics, record, x0, solver=solver)
        return y, y.new_zeros(len(record.t), y.shape[-1], 0)


@dataclass(frozen=True)
class Estimate(InitialState):
    """Each record's initial state is estimated: with the parameters on the training records, with the parameters
    fixed on each validation record's start window, which is not scored (module docstring)."""

    estimated: ClassVar[bool] = True
    name: ClassVar[str] = "estimate"

    def unknowns(self, physics, records):
        return physics.state_dim * len(records)

    def labels(self, physics, records):
        return [f"x0[{r.name}].{s}" for r in records for s in physics.state_names]

    def guesses(self, physics, records, start_states):
        if start_states is not None and len(start_states) != len(records):
            raise ConfigurationError(f"start_states needs one state per record ({len(records)}), got "
                                     f"{len(start_states)}")
        given = [None] * len(records) if start_states is None else start_states
        return [complete_state(physics, None if x is None else x.detach().reshape(1, -1), 1)[0].numpy()
                for x in given]

    def states(self, physics, records, values):
        n = physics.state_dim
        return [torch.from_numpy(values[i * n:(i + 1) * n].copy())[None] for i in range(len(records))]

    def carried(self, states):
        return states

    def validation_starts(self, records, estimate):
        return [estimate(r.window(0, self.scored_from(r))) for r in records]

    def scored_from(self, record):
        return start_window(len(record.t), f"record {record.name!r}")

    def free_response(self, physics, record, x0, solver):
        y, J = record_jacobian(physics, [], record, x0, initial_state=True, solver=solver)
        return y, J[0]


_POLICIES = {policy.name: policy for policy in (Rest(), Estimate())}


def policy_named(name: str) -> InitialState:
    """The policy a config or the command line names: ``"rest"`` or ``"estimate"``."""
    if name not in _POLICIES:
        raise ConfigurationError(f"initial_state must be 'rest' or 'estimate', got {name!r}")
    return _POLICIES[name]


def as_initial_state(value: str | InitialState) -> InitialState:
    """The policy ``value`` names: a policy itself, or (deprecated: the strings go in the next release) ``"rest"``
    or ``"estimate"``."""
    if isinstance(value, InitialState):
        return value
    if value not in _POLICIES:
        raise ConfigurationError(f"initial_state must be Rest() or Estimate() (deprecated: 'rest' or 'estimate'), got "
                                 f"{value!r}")
    warnings.warn(f"initial_state={value!r} is deprecated: pass {type(_POLICIES[value]).__name__}() (the strings go "
                  "in the next release)", DeprecationWarning, stacklevel=3)
    return _POLICIES[value]
