"""The simulator's entries for a measured record: each reads the record's time, input and ``hold`` here.

Everything above the simulation layer (fits, the ranking, discovery) simulates records through these, so
that a record's input is held as it says (``Experiment.hold``: linear between samples, or held) in every
simulation, and nobody passes ``hold=`` by hand. Time is shifted to start at 0; ``x0`` is a state (n_state,)
or (1, n_state), rest when omitted.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._simulate.response import forced_response
from torchpaml._simulate.sensitivity import output_jacobian
from torchpaml._simulate.shooting import simulate_shooting
from torchpaml._simulate.solvers import FixedStep, engine_solver
from torchpaml._simulate.warm import WarmStart

if TYPE_CHECKING:  # records are built on the simulator (the Simulated source): imported for annotations only
    from torchpaml._data import Experiment

__all__ = ["record_jacobian", "record_output", "record_response", "record_states", "simulate_record"]


def _start(x0: torch.Tensor | None) -> torch.Tensor | None:
    return None if x0 is None else x0.reshape(1, -1)


def record_output(physics: AbstractPhysics, record: Experiment, x0: torch.Tensor | None = None,
                  **options) -> torch.Tensor:
    """The model's output on ``record``, (1, time, n_output), differentiable when grad mode is on; ``options``
    go to :func:`~torchpaml.simulate` (through the model's ``forward``: its own ``solver`` unless given one)."""
    return physics(record.t - record.t[0], record.u[None], _start(x0), hold=record.hold, **options)


def simulate_record(physics: AbstractPhysics, record: Experiment, x0: torch.Tensor | None = None,
                    **options) -> torch.Tensor:
    """The model's output on one record from ``x0`` (n_state,) or rest, (1, time, n_output), without gradients;
    the input held as the record's ``hold`` says."""
    with torch.no_grad():
        return record_output(physics, record, x0, **options)


def record_states(physics: AbstractPhysics, record: Experiment, x0: torch.Tensor | None = None,
                  solver: FixedStep | None = None) -> torch.Tensor:
    """The states on ``record`` by the shooting engine with ``solver`` (default the model's,
    :func:`~torchpaml._simulate.solvers.engine_solver`), (time, n_state), without gradients."""
    start = physics.initial_state(1) if x0 is None else _start(x0)
    with torch.no_grad():
        return simulate_shooting(physics, record.t - record.t[0], record.u[None], start,
                                 engine_solver(physics) if solver is None else solver, hold=record.hold)[0]


def record_jacobian(physics: AbstractPhysics, names: Sequence[str], record: Experiment,
                    x0: torch.Tensor | None = None, warm: WarmStart | None = None, initial_state: bool = False,
                    solver: FixedStep | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`~torchpaml._simulate.sensitivity.output_jacobian` on ``record``: the output and its Jacobian in
    the raw parameters ``names`` (and, with ``initial_state``, in ``x0``)."""
    return output_jacobian(physics, names, record.t - record.t[0], record.u[None], _start(x0), warm=warm,
                           initial_state=initial_state, hold=record.hold, solver=solver)


def record_response(physics: AbstractPhysics, record: Experiment, x0: torch.Tensor, rates: torch.Tensor
                    ) -> torch.Tensor:
    """:func:`~torchpaml._simulate.response.forced_response` on ``record``: what each of ``rates`` (k, time,
    n_state) does to the output to first order, (k, time, n_output)."""
    return forced_response(physics, record.t - record.t[0], record.u[None], _start(x0), rates, record.hold)
