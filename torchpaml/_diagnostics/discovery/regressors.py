r"""The discovery's regression data (:mod:`~torchpaml._diagnostics.discovery.result`, step 2): each library term's response
through the physics along the neural model's trajectories, the learned rate's, the measured residual, and the
physics' own sensitivities, records concatenated. With several output channels every channel's samples are rows,
each channel weighted by $1/\mathrm{RMS}(y_c)$ (:func:`~torchpaml._metrics.channel_weights`)."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._data import Record
from torchpaml._data.simulation import record_response, record_states
from torchpaml._diagnostics.ranking.probes import assigned
from torchpaml._diagnostics.results import ModelScore
from torchpaml._fit.initial_state import InitialState
from torchpaml._fit.neural_force import NeuralForceFit
from torchpaml._metrics import channel_weights
from torchpaml._physics.terms import compile_term, input_values, state_columns, width_symbol

__all__ = ["Columns", "RESPONSE_BATCH", "columns", "width_range"]

log = logging.getLogger(__name__)

#: The terms' rates pass through the physics' tangent-linear response this many at a time, a progress line each.
RESPONSE_BATCH = 64

#: Relative central-difference step of the physics' own sensitivities.
STEP = 1e-6


def width_range(values: torch.Tensor) -> tuple[float, float]:
    r"""The smoothed sign's widths that a record of ``values`` (samples,) resolves: from the median change over
    one sample (a narrower sign is a sign at this sampling) to the RMS (a wider one is linear where the
    values lie)."""
    low = float(values.diff().abs().median())
    high = float(values.square().mean().sqrt())
    return max(low, 1e-9 * high, 1e-300), max(high, 2 * low, 1e-300)


@dataclass
class Columns:
    """The regression's data, records concatenated: the terms' responses (samples, columns), the learned rate's
    (samples,), the measured residual (samples,), the physics' Jacobian (samples, p), the raw term values on the
    first record's trajectory, and each sign variable's width range."""

    responses: torch.Tensor
    learned: torch.Tensor
    measured: torch.Tensor
    jacobian: torch.Tensor
    samples: dict[str, torch.Tensor]
    widths: dict[str, tuple[float, float]]


def columns(neural: NeuralForceFit, baseline: ModelScore, terms: list[str], equations: dict[str, int],
             variables: tuple[str, ...], train: Sequence[Record], initial_state: InitialState) -> Columns:
    """:class:`Columns` along the neural model's trajectories (module docstring, step 2), around the fitted physics
    of ``baseline`` from its training records' initial states."""
    physics, solver, starts = baseline.model, baseline.solver, baseline.train_states
    compiled = [compile_term(t, variables) for t in terms]
    trajectories = [record_states(neural.model, record, x0, neural.solver)
                    for record, x0 in zip(train, starts, strict=True)]
    index = state_columns(physics)
    signs = sorted({w for c in compiled for w in c.widths})
    by_width = {width_symbol(s): s for s in index}
    widths = {w: width_range(torch.cat([x[:, index[by_width[w]]] for x in trajectories])) for w in signs}
    names = physics.learnable_names()
    parts: dict[str, list[torch.Tensor]] = {"responses": [], "learned": [], "measured": [], "jacobian": []}
    samples: dict[str, torch.Tensor] = {}
    n, outputs = physics.state_dim, physics.output_dim
    weights = channel_weights([r.y for r in train])
    for record, x0, states in zip(train, starts, trajectories, strict=True):
        values = {name: states[:, i] for name, i in index.items()}
        values.update(input_values(physics, record.u))
        values.update({w: torch.tensor(2 * low, dtype=states.dtype) for w, (low, _) in widths.items()})
        rates = []
        for equation, state in equations.items():
            for term in compiled:
                rate = torch.zeros(len(record.t), n, dtype=states.dtype)
                rate[:, state] = term.evaluate(values)
                rates.append(rate)
        with torch.no_grad():
            learned = neural.model.learned(states, record.u)
        forcing = [*rates, learned]
        responses = []
        for start in range(0, len(forcing), RESPONSE_BATCH):  # a progress line per batch: none runs for minutes
            log.info("discovery: responses %d-%d of %d through the physics, record %r", start + 1,
                     min(start + RESPONSE_BATCH, len(forcing)), len(forcing), record.name)
            responses.append(record_response(physics, record, x0, torch.stack(forcing[start:start + RESPONSE_BATCH]),
                                             solver))
        responses = torch.cat(responses) * weights
        parts["responses"].append(responses[:-1].reshape(len(rates), -1).T)  # rows: samples, then channels
        parts["learned"].append(responses[-1].reshape(-1))
        y, free = initial_state.free_response(physics, record, x0, solver)  # (time, n_output, k): k = 0 at rest
        own = _own_sensitivities(physics, names, states, record.u)  # (N, n + n_output, p)
        own_responses = record_response(physics, record, x0, own[:, :n].movedim(-1, 0), solver)
        columns = own_responses.movedim(0, -1) + own[:, n:n + outputs, :]  # (N, n_output, p)
        columns = torch.cat([columns, free], dim=-1)  # the initial states' free responses
        parts["measured"].append(((record.y - y[0]) * weights).reshape(-1))
        parts["jacobian"].append((columns * weights[:, None]).reshape(len(record.t) * outputs, -1))
        if not samples:
            first = next(iter(equations.values()))
            samples = {**{v: values[v] for v in variables}, "learned": learned[:, first]}
    return Columns(*(torch.cat(parts[k]) for k in ("responses", "learned", "measured", "jacobian")), samples, widths)


def _own_sensitivities(physics: AbstractPhysics, names: list[str], states: torch.Tensor,
                       u: torch.Tensor) -> torch.Tensor:
    r"""$\partial f/\partial\theta_j$ and $\partial h/\partial\theta_j$ at the given states, (N, n_state + n_output, p),
    by central differences in each physical parameter $\theta_j$: what the physics' own parameters can change,
    evaluated on the same trajectory as the terms."""
    t = torch.zeros(len(states), dtype=states.dtype)
    values = physics.physical_parameters()
    columns = []
    with torch.no_grad():
        for name in names:
            step = STEP * max(1.0, abs(values[name]))
            ends = []
            value = values[name]
            points = next(p for p in ((value + step, value - step), (value + step, value), (value + 2 * step, value + step))
                          if assigned(physics, name, p[1]))  # one-sided at a constraint's edge
            for point in points:
                physics.assign(**{name: point})
                ends.append(torch.cat([physics.derivative(t, states, u), physics.output(states, u)], dim=-1))
            assigned(physics, name, value)
            columns.append((ends[0] - ends[1]) / (points[0] - points[1]))
    width = physics.state_dim + physics.output_dim
    return torch.stack(columns, dim=-1) if columns else torch.zeros(len(states), width, 0, dtype=states.dtype)
