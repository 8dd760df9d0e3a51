r"""The least-squares problem of :func:`~torchpaml.fit_physics`, as ``scipy.optimize.least_squares`` asks for it.

The unknowns $x$ are the raw values $\rho$ of the learnable parameters, then (with ``Estimate()``) each record's
initial state; the residual is $r = (y - \hat y)/s$ over all records stacked, $s$ each output channel's scale
(:func:`~torchpaml._metrics.channel_scales`: $\|y\|$ for one channel, so that $\|r\|$ is the
:func:`~torchpaml.mismatch`), and its Jacobian comes from
:func:`~torchpaml._data.simulation.record_jacobian`, each record's initial-state columns in its own block.
"""

from __future__ import annotations

import contextlib
import math
import time

import numpy as np
import torch

from torchpaml._budget import Budget
from torchpaml._data import Record
from torchpaml._data.simulation import record_jacobian
from torchpaml._errors import SimulationError
from torchpaml._metrics import sample_scales
from torchpaml._fit.initial_state import InitialState
from torchpaml._physics.base import AbstractPhysics
from torchpaml._simulate.sensitivity import raw_parameters
from torchpaml._simulate.solvers import Solver
from torchpaml._simulate.warm import WarmStart

__all__ = ["TrustRegionProblem"]


class TrustRegionProblem:
    """Residual and Jacobian at a point $x$ (module docstring), each point computed once (a memo of the last), with
    the simulations counted and the lowest cost kept; ``solver`` is the solver of the records'
    simulations, which the step check may replace (:meth:`use`)."""

    def __init__(self, physics: AbstractPhysics, records: list[Record], names: list[str], initial_state: InitialState,
                 solver: Solver, warm: list[WarmStart], budget: Budget | None):
        self.physics, self.records, self.names, self.initial_state = physics, records, names, initial_state
        self.with_states = initial_state.unknowns(physics, records) > 0  # the Jacobian's initial-state columns
        self.solver, self.warm, self.budget = solver, warm, budget
        self.raw = list(raw_parameters(physics, names).values())
        self.targets = [r.y[None] for r in records]
        self.scale = sample_scales(self.targets)  # each sample's channel scale: the residual is the mismatch's
        self.simulations, self.cost = 0, math.inf  # the lowest cost so far
        self._memo: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    @property
    def samples(self) -> int:
        return sum(y.numel() for y in self.targets)

    def use(self, solver: Solver) -> None:
        """Simulate by ``solver`` from now on (the points already computed no longer count)."""
        if solver != self.solver:
            self.solver = solver
            self._memo.clear()

    def start(self, start_states, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """The first point: the parameters' current raw values, then each record's starting state (``start_states``
        or rest), inside the bounds."""
        guesses = self.initial_state.guesses(self.physics, self.records, start_states)
        values = torch.stack([v.detach() for v in self.raw]).numpy() if self.raw else np.zeros(0)
        return np.clip(np.concatenate([values, *guesses]), lower, upper)

    def starts(self, x: np.ndarray) -> list[torch.Tensor | None]:
        """Each record's initial state (1, n_state) at ``x``, ``None`` (rest) where it is not estimated."""
        return self.initial_state.states(self.physics, self.records, x[len(self.names):])

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual (samples,) and Jacobian (samples, unknowns) at ``x``, once per point, within the budget."""
        key = x.tobytes()
        if key not in self._memo:
            self.simulations += 1
            began = time.perf_counter()
            try:
                with self.budget.active() if self.budget is not None else contextlib.nullcontext():
                    value = self._computed(x)
                self._memo.clear()
                self._memo[key] = value
                self.cost = min(self.cost, 0.5 * float(np.sum(value[0] ** 2)))
            finally:  # a blow-up's time counts too
                if self.budget is not None:
                    self.budget.check(self.cost, time.perf_counter() - began)
        return self._memo[key]

    def residual(self, x: np.ndarray) -> np.ndarray:
        """The residual at ``x``; inf where the simulation blows up (the trust region then rejects the step)."""
        try:
            return self.evaluate(x)[0]
        except SimulationError:
            return np.full(self.samples, np.inf)

    def outputs(self, residual: np.ndarray) -> list[torch.Tensor]:
        """Each record's output (time, n_output) from the residual $r = (y - \\hat y)/s$."""
        parts = (torch.from_numpy(residual) * self.scale).split([y.numel() for y in self.targets])
        return [y[0] - part.reshape(y.shape[1:]) for y, part in zip(self.targets, parts, strict=True)]

    def _computed(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with torch.no_grad():
            for tensor, value in zip(self.raw, x, strict=False):
                tensor.copy_(torch.tensor(value, dtype=torch.float64))
        parts = [record_jacobian(self.physics, self.names, r, x0, warm=w, initial_state=self.with_states,
                                 solver=self.solver)
                 for r, w, x0 in zip(self.records, self.warm, self.starts(x), strict=True)]
        residual = torch.cat([(y - y_hat).flatten() for y, (y_hat, _) in zip(self.targets, parts, strict=True)])
        p = len(self.names)
        columns = []
        for i, (_, J) in enumerate(parts):  # each record's x0 columns go to its own block
            J = J.reshape(-1, J.shape[-1])
            block = torch.zeros(len(J), len(x) - p, dtype=torch.float64)
            block[:, i * (J.shape[1] - p):(i + 1) * (J.shape[1] - p)] = J[:, p:]  # none at rest
            columns.append(torch.cat([J[:, :p], block], dim=1))
        return (residual / self.scale).numpy(), (-torch.cat(columns) / self.scale[:, None]).numpy()
