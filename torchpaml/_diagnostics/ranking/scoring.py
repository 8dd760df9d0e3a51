"""A fitted model scored on the validation records: its mismatch, and the selection rule's criterion."""

from __future__ import annotations

from collections.abc import Sequence

import torch

from torchpaml._data import Record
from torchpaml._data.simulation import simulate_record
from torchpaml._diagnostics.results import ModelScore
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._fit.initial_state import InitialState, Rest, as_initial_state
from torchpaml._fit.physics_fit import PhysicsEstimate, estimate_initial_state
from torchpaml._metrics import mismatch
from torchpaml._physics.base import AbstractPhysics
from torchpaml._simulate.solvers import Auto

__all__ = ["as_records", "score_model"]


def as_records(experiments: Record | Sequence[Record]) -> list[Record]:
    return [experiments] if isinstance(experiments, Record) else list(experiments)


def score_model(
    physics: AbstractPhysics,
    fit: PhysicsEstimate,
    validation: Sequence[Record],
    rule: SelectionRule | None = None,
    initial_state: str | InitialState = Rest(),
) -> ModelScore:
    """The fitted ``physics``' mismatch on training (from ``fit``) and validation, and ``rule``'s criterion on
    validation.

    With several output channels, the validation mismatch is :func:`~torchpaml.mismatch`'s (the root mean square of
    the channels' mismatches) and the criterion reads the squared error in units of each channel's mean square,
    $n m^2$, so that no channel's unit outweighs another's; with one, the squared error in the data's unit.

    With ``Estimate()`` each validation record starts from the state that best explains
    it (:func:`~torchpaml.estimate_initial_state`, the parameters fixed), as MATLAB's ``compare`` does.
    """
    initial_state = as_initial_state(initial_state)
    sse, n, norm = 0.0, 0, 0.0
    starts = initial_state.validation_starts(
        validation, lambda record: estimate_initial_state(physics, record, solver=Auto(start=fit.solver)))
    outputs = []
    for record, x0 in zip(validation, starts, strict=True):
        y_model = simulate_record(physics, record, x0, solver=fit.solver)[0]
        outputs.append(y_model)
        sse += float(torch.sum((record.y - y_model) ** 2))
        norm += float(torch.sum(record.y**2))
        n += record.y.numel()
    validation_mismatch = (sse / norm) ** 0.5
    if validation[0].y.shape[-1] > 1:
        validation_mismatch = mismatch(torch.cat([r.y for r in validation]), torch.cat(outputs))
        sse = n * validation_mismatch**2
    value = (rule or SelectionRule()).value(sse, n, len(fit.parameters))
    equation = physics.equation()
    return ModelScore(physics.display_name, equation, physics.physical_parameters(), fit.mismatch,
                      validation_mismatch, value, physics, dict(fit.uncertainty.std), fit.uncertainty.warning,
                      fit.initial_states, [physics.initial_state(1)[0] if x0 is None else x0 for x0 in starts],
                      outputs, fit.solver, dict(fit.uncertainty.interval), fit, samples=n)
