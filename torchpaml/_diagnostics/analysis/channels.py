r"""Where the model fails, output by output: each channel's mismatch before and after the ladder, and its analysis.

With several output channels, a missing effect rarely shows the same on each: Coulomb friction on the second mass
of a chain shows most on the second position. :func:`channel_scores` scores each output channel $c$ on the
validation records, $m_c = \|y_c - \hat y_c\| / \|y_c\|$ (:func:`~torchpaml.channel_mismatch`) of the fitted
physics and of the final model, with that channel's residual analysis against the first input
(:func:`~torchpaml.residual_analysis`) and its mismatch by amplitude (:func:`~torchpaml.error_by_amplitude`), on the
first validation record. :func:`shows_most` names the channel where the ladder's effects lowered the mismatch most
(or, where it added none, where the physics fails most). The overall mismatch is the root mean square of the
channels' (:func:`~torchpaml.mismatch`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from torchpaml._data import Record
from torchpaml._diagnostics.analysis.residuals import ResidualAnalysis, residual_analysis
from torchpaml._diagnostics.results import ModelScore
from torchpaml._diagnostics.analysis.validity import AmplitudeBins, error_by_amplitude
from torchpaml._metrics import channel_mismatch

__all__ = ["ChannelScore", "channel_scores", "shows_most"]


@dataclass
class ChannelScore:
    """One output channel on the validation records: its name, the fitted physics' and the final model's mismatch
    there (fractions) and RMSE (the data's unit), and, for the fitted physics on the first validation record, its
    residual analysis against the first input and its mismatch by |u| and by |y|."""

    name: str
    physics: float
    final: float
    rmse_physics: float
    rmse_final: float
    residuals: ResidualAnalysis
    by_input: AmplitudeBins
    by_output: AmplitudeBins


def _joined(step: ModelScore, validation: list[Record]) -> tuple[torch.Tensor, torch.Tensor]:
    return torch.cat([r.y for r in validation]), torch.cat(step.validation_outputs)


def channel_scores(physics: ModelScore, final: ModelScore, validation: list[Record]) -> list[ChannelScore]:
    """Each output channel's :class:`ChannelScore` (module docstring), in the records' order, named as the first
    validation record names it, else as the physics does (``output_names``), else ``y1, y2, …``."""
    y, y_physics = _joined(physics, validation)
    _, y_final = _joined(final, validation)
    before, after = channel_mismatch(y, y_physics), channel_mismatch(y, y_final)
    rmse_before, rmse_after = ((y - out).square().mean(dim=0).sqrt() for out in (y_physics, y_final))
    record, model = validation[0], physics.validation_outputs[0]
    named = "outputs" in record.metadata or not physics.model.output_names
    scores = []
    for c, name in enumerate(record.output_names if named else physics.model.output_names):
        error = (record.y - model)[:, c]
        scores.append(ChannelScore(name, float(before[c]), float(after[c]), float(rmse_before[c]),
                                   float(rmse_after[c]), residual_analysis(record.u[:, 0], error),
                                   error_by_amplitude(record.u[:, 0], record.y[:, c], model[:, c]),
                                   error_by_amplitude(record.y[:, c], record.y[:, c], model[:, c])))
    return scores


def shows_most(channels: list[ChannelScore], added: bool) -> ChannelScore:
    """The channel where the effects the ladder ``added`` lowered the mismatch most; where it added none, the one
    where the physics fails most."""
    if added:
        return max(channels, key=lambda c: c.physics - c.final)
    return max(channels, key=lambda c: c.physics)
