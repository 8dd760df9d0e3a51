"""A fitted physics with the solver it was fitted with: one value that simulates a record as the fit did."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from torchpaml._data import Record
from torchpaml._data.simulation import record_states, simulate_record
from torchpaml._physics.base import AbstractPhysics
from torchpaml._simulate.solvers import Solver

__all__ = ["FittedModel"]


@dataclass(frozen=True)
class FittedModel:
    """``physics`` (its parameters as fitted) and ``solver``, the one it was fitted with
    (``PhysicsEstimate.solver``): ``fit.model.simulate(record)`` simulates a record as the fit did.

    Attributes:
        physics: the fitted physics (the module itself: a later fit of it changes what this simulates).
        solver: the solver that simulates it as fitted (:meth:`~torchpaml.Solver.simulating`).
    """

    physics: AbstractPhysics
    solver: Solver

    def simulate(self, record: Record, x0: torch.Tensor | None = None) -> torch.Tensor:
        """The output on ``record`` from ``x0`` (n_state,) or rest, (time, n_output), the input held as the record
        says, without gradients."""
        return simulate_record(self.physics, record, x0, solver=self.solver)[0]

    def states(self, record: Record, x0: torch.Tensor | None = None) -> torch.Tensor:
        """The states on ``record`` from ``x0`` or rest, (time, n_state), without gradients."""
        return record_states(self.physics, record, x0, self.solver)
