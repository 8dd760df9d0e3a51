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

__all__ = ["as_records", "score_model", "scored_mismatch"]


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

    With ``Estimate()`` each validation record starts from the state that best explains its start window
    (:func:`~torchpaml.estimate_initial_state`, the parameters fixed) and is scored after it
    (:mod:`~torchpaml._fit.initial_state`); ``ModelScore.validation_outputs`` hold the whole records' outputs.
    """
    initial_state = as_initial_state(initial_state)
    starts = initial_state.validation_starts(
        validation, lambda window: estimate_initial_state(physics, window, solver=Auto(start=fit.solver)))
    outputs = [simulate_record(physics, record, x0, solver=fit.solver)[0]
               for record, x0 in zip(validation, starts, strict=True)]
    measured, scored = _scored(validation, outputs, initial_state)
    validation_mismatch = mismatch(measured, scored)
    n = measured.numel()
    sse = n * validation_mismatch**2 if measured.shape[-1] > 1 else float(torch.sum((measured - scored) ** 2))
    value = (rule or SelectionRule()).value(sse, n, len(fit.parameters))
    equation = physics.equation()
    return ModelScore(physics.display_name, equation, physics.physical_parameters(), fit.mismatch,
                      validation_mismatch, value, physics, dict(fit.uncertainty.std), fit.uncertainty.warning,
                      fit.initial_states, [physics.initial_state(1)[0] if x0 is None else x0 for x0 in starts],
                      outputs, fit.solver, dict(fit.uncertainty.interval), fit, samples=n)


def _scored(validation: Sequence[Record], outputs: Sequence[torch.Tensor], initial_state: InitialState
            ) -> tuple[torch.Tensor, torch.Tensor]:
    """The measured and the model's outputs on the samples each validation record is scored on (from
    ``initial_state.scored_from(record)``), joined in time: (samples, n_y) each."""
    first = [initial_state.scored_from(record) for record in validation]
    return (torch.cat([record.y[k:] for record, k in zip(validation, first, strict=True)]),
            torch.cat([output.detach()[k:] for output, k in zip(outputs, first, strict=True)]))


def scored_mismatch(validation: Sequence[Record], outputs: Sequence[torch.Tensor],
                    initial_state: str | InitialState) -> float:
    """:func:`~torchpaml.mismatch` of a model's ``outputs`` (one (time, n_y) per validation record) on the samples
    :func:`score_model` scores: with ``Estimate()``, those after each record's start window. Every validation
    figure of a diagnosis (a rung, a probe, the hybrid, the discovery's neural rate) is this one measure."""
    return mismatch(*_scored(validation, outputs, as_initial_state(initial_state)))
