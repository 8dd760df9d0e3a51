"""A record through the simulator: each entry reads the record's time, input and ``hold`` here, and the simulator
sees tensors only.

Everything above the data layer (fits, the ranking, discovery) simulates records through these, so
that a record's input is held as it says (``Record.hold``: linear between samples, or held) in every
simulation, and nobody passes ``hold=`` by hand. Time starts at 0 (:attr:`Record.elapsed`); ``x0`` is a state
(n_state,) or (1, n_state), rest when omitted; ``solver`` is how the model was fitted (``PhysicsEstimate.solver``).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from torchpaml._data.record import Record
from torchpaml._physics.base import AbstractPhysics
from torchpaml._simulate.response import forced_response
from torchpaml._simulate.simulator import output_jacobian, simulate
from torchpaml._simulate.solvers import Auto, Solver
from torchpaml._simulate.warm import WarmStart

__all__ = ["record_jacobian", "record_output", "record_response", "record_states", "simulate_record"]


def _start(x0: torch.Tensor | None) -> torch.Tensor | None:
    """``x0`` (n_state,) as the one row (1, n_state) of float64 the simulators take."""
    return None if x0 is None else torch.as_tensor(x0, dtype=torch.float64).reshape(1, -1)


def record_output(physics: AbstractPhysics, record: Record, x0: torch.Tensor | None = None,
                  **options) -> torch.Tensor:
    """The model's output on ``record``, (1, time, n_output), differentiable when grad mode is on; ``options``
    (``solver``, ``warm``) go to :func:`~torchpaml.simulate`."""
    return simulate(physics, record.elapsed, record.u[None], _start(x0), hold=record.hold, **options)


def simulate_record(physics: AbstractPhysics, record: Record, x0: torch.Tensor | None = None,
                    **options) -> torch.Tensor:
    """The model's output on one record from ``x0`` (n_state,) or rest, (1, time, n_output), without gradients;
    the input held as the record's ``hold`` says."""
    with torch.no_grad():
        return record_output(physics, record, x0, **options)


def record_states(physics: AbstractPhysics, record: Record, x0: torch.Tensor | None = None,
                  solver: Solver | None = None) -> torch.Tensor:
    """The states on ``record`` at the resolution of ``solver`` (a fit's ``PhysicsEstimate.solver``;
    :meth:`~torchpaml.Solver.states` of ``Auto(start=solver)``), (time, n_state), without gradients."""
    start = physics.initial_state(1) if x0 is None else _start(x0)
    with torch.no_grad():
        return Auto(start=solver).states(physics, record.elapsed, record.u[None], start, hold=record.hold)[0]


def record_jacobian(physics: AbstractPhysics, names: Sequence[str], record: Record,
                    x0: torch.Tensor | None = None, warm: WarmStart | None = None, initial_state: bool = False,
                    solver: Solver | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`~torchpaml._simulate.simulator.output_jacobian` on ``record``: the output and its Jacobian in
    the raw parameters ``names`` (and, with ``initial_state``, in ``x0``) at the resolution of ``solver``."""
    return output_jacobian(physics, names, record.elapsed, record.u[None], _start(x0), warm=warm,
                           initial_state=initial_state, hold=record.hold, solver=solver)


def record_response(physics: AbstractPhysics, record: Record, x0: torch.Tensor, rates: torch.Tensor,
                    solver: Solver | None = None) -> torch.Tensor:
    """:func:`~torchpaml._simulate.response.forced_response` on ``record``: what each of ``rates`` (k, time,
    n_state) does to the output to first order, (k, time, n_output)."""
    return forced_response(physics, record.elapsed, record.u[None], _start(x0), rates, record.hold, solver)
