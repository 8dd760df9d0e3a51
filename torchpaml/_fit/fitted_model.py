"""A fitted physics with the solver it was fitted with: one value that simulates a record as the fit did, and that a
model file (:func:`~torchpaml.save_model`) keeps whole: the residual on top, the channels, the hold, the initial-state
policy and the parameters' uncertainty."""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from torchpaml._data import Record
from torchpaml._data.simulation import record_states, simulate_record
from torchpaml._fit.initial_state import InitialState, Rest
from torchpaml._fit.uncertainty import Uncertainty
from torchpaml._physics.base import AbstractPhysics
from torchpaml._residual.base import AbstractResidual
from torchpaml._simulate.solvers import Solver

__all__ = ["FittedModel"]


@dataclass(frozen=True)
class FittedModel:
    """``physics`` (its parameters as fitted) and ``solver``, the one it was fitted with
    (``PhysicsEstimate.solver``): ``fit.model.simulate(record)`` simulates a record as the fit did.

    Attributes:
        physics: the fitted physics (the module itself: a later fit of it changes what this simulates).
        solver: the solver that simulates it as fitted (:meth:`~torchpaml.Solver.simulating`).
        residual: a residual added to the physics' output (the orthogonal one of a hybrid), or ``None``.
        inputs, outputs: the channels' names, as the records named them (empty: unnamed).
        hold: how the input moves between samples, as in the records it was fitted on (``"foh"``, ``"zoh"``).
        initial_state: the policy that started the records it was scored on (:func:`~torchpaml.predict` follows it).
        uncertainty: the fit's standard errors and correlations of the parameters, or ``None``.
        step: the records' sampling interval (s), where it is uniform, else ``None`` (an exporter's step for a model
            simulated exactly).
        noise: each output's residual RMS on the records it was scored on (the measurement noise where the model is
            right: a tracker's noise level), or empty.
    """

    physics: AbstractPhysics
    solver: Solver
    residual: AbstractResidual | None = None
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    hold: str = "foh"
    initial_state: InitialState = field(default_factory=Rest)
    uncertainty: Uncertainty | None = field(default=None, repr=False)
    step: float | None = None
    noise: tuple[float, ...] = ()

    def simulate(self, record: Record, x0: torch.Tensor | None = None) -> torch.Tensor:
        r"""The output on ``record`` from ``x0`` (n_state,) or rest, (time, n_output), the input held as the record
        says, without gradients: $\hat y = h(x, u) + r(u)$, the residual's $r$ where there is one."""
        y = simulate_record(self.physics, record, x0, solver=self.solver)[0]
        if self.residual is None:
            return y
        with torch.no_grad():
            return y + self.residual(record.elapsed, record.u[None], y[None])[0]

    def states(self, record: Record, x0: torch.Tensor | None = None) -> torch.Tensor:
        """The states on ``record`` from ``x0`` or rest, (time, n_state), without gradients."""
        return record_states(self.physics, record, x0, self.solver)
