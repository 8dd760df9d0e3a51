r"""A neural rate inside the ODE, fitted by output error with the physics held: a universal differential equation.

$$ \dot x = f_{\hat\theta}(t, x, u) + E\,\mathrm{MLP}_w(x/s_x, u/s_u), \qquad
   \hat w = \arg\min_w \sum_{\text{records}} \|y - \hat y_w\|^2 / \|y\|^2 $$

with $\hat\theta$ the physics-only estimates (fixed), $E$ the columns of the equations the rate
enters (the velocity's for second-order physics, where it is a force; every state's otherwise:
:func:`~torchpaml._physics.terms.variables_of`), $s_x$ the standard deviations of the physics' own
states on the records and $s_u$ that of the input. The network (:class:`~torchpaml._residual.mlp.MLPRate`,
its last layer at zero, so the fit starts from the physics) is simulated by the parallel RK4 engine,
each record's Newton solve warm-started from the previous iterate's trajectory, and fitted by L-BFGS
(:func:`~torchpaml._fit.output_error.minimize_output_error`). The hidden layers' initial weights come
from ``seed``, so the fit is reproducible.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from torchpaml._budget import Budget, OverBudget
from torchpaml._physics.base import AbstractPhysics
from torchpaml._data import Record
from torchpaml._fit.output_error import minimize_output_error
from torchpaml._metrics import channel_weights
from torchpaml._physics.terms import variables_of
from torchpaml._residual.mlp import MLPRate, RateAugmented
from torchpaml._data.simulation import record_output, record_states
from torchpaml._simulate.warm import WarmStart
from torchpaml._simulate.solvers import Auto, FixedStep, Solver

__all__ = ["NeuralForceFit", "fit_neural_force"]

log = logging.getLogger(__name__)


@dataclass
class NeuralForceFit:
    """Result of :func:`fit_neural_force`: the universal differential equation, its training mismatch, and the
    fixed-step solver it was fitted (and is simulated) with."""

    model: RateAugmented
    mismatch: float
    iterations: int
    solver: FixedStep
    #: the seconds after which the fit stopped over its budget, the network where the search stood; else ``None``
    stopped: float | None = None


def fit_neural_force(
    physics: AbstractPhysics,
    records: Sequence[Record],
    initial_states: Sequence[torch.Tensor] | None = None,
    *,
    hidden: int = 32,
    depth: int = 2,
    max_iter: int = 60,
    seed: int = 0,
    solver: Solver | None = None,
    budget: Budget | None = None,
) -> NeuralForceFit:
    """Fit a neural rate on top of ``physics`` (not modified: a frozen copy is used) to ``records``.

    Args:
        physics: any physics, at its fitted parameters.
        records: training records.
        initial_states: each record's initial state (n_state,); rest if omitted.
        hidden: width of each hidden tanh layer of the network.
        depth: number of hidden tanh layers of the network.
        max_iter: L-BFGS iterations.
        seed: seed of the network's initial weights.
        solver: the solver ``physics`` was fitted with (its fixed-step method at its substeps integrates the network
            too: :meth:`~torchpaml.Solver.stepping` of ``Auto(start=solver)``).
        budget: a :class:`~torchpaml.Budget`: progress lines, and over its limit the network stays where the search
            stood (``NeuralForceFit.stopped``).
    """
    solver = Auto(start=solver).stepping()
    frozen = copy.deepcopy(physics)
    frozen.set_learnable(*frozen.learnable_names(), learn=False)
    _, equations = variables_of(frozen)
    starts = [frozen.initial_state(1) if x0 is None else x0.reshape(1, -1)
              for x0 in (initial_states or [None] * len(records))]
    states = torch.cat([record_states(frozen, r, x0, solver) for r, x0 in zip(records, starts, strict=True)])
    inputs = torch.cat([r.u for r in records])
    scales = [float(s.std()) or 1.0 for s in (*states.T, *inputs.T)]
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        rate = MLPRate(scales, len(equations), hidden, depth)
    model = RateAugmented(frozen, rate, list(equations.values()))
    warm = [WarmStart() for _ in records]

    weights = channel_weights([r.y for r in records])  # several outputs weigh the same; one: unchanged

    def predict() -> torch.Tensor:
        return torch.cat([(record_output(model, r, x0, solver=solver, warm=w) * weights).flatten()
                          for r, x0, w in zip(records, starts, warm, strict=True)])

    target = torch.cat([(r.y * weights).flatten() for r in records])
    try:
        loss, iterations = minimize_output_error(predict, target, list(rate.parameters()), max_iter=max_iter,
                                                 budget=budget)
    except OverBudget as over:
        log.info("%s; the discovery goes on from the network where it stood", over)
        with torch.no_grad():
            loss = float(torch.sum((target - predict()) ** 2) / torch.sum(target**2))
        return NeuralForceFit(model, loss**0.5, max_iter, solver, over.seconds)
    return NeuralForceFit(model, loss**0.5, iterations, solver)
