r"""``compare``: how well each model reproduces each measured experiment (MATLAB's ``compare``).

For every (experiment, model) pair the model is simulated from rest on the experiment's input and
scored against its output: mismatch $= \|y - \hat y\| / \|y\|$ (%), fit $= 100\,(1 - \|y - \hat y\| / \|y - \bar y\|)$
(%), and RMSE in the data's units.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import torch

from torchpaml._errors import ConfigurationError
from torchpaml._data import Record
from torchpaml._metrics import fit_percent, mismatch, rmse

__all__ = ["Comparison", "compare"]


@dataclass
class Comparison:
    """Scores per (experiment, model), and the simulated outputs for the figures.

    ``rows``: dicts ``{experiment, model, mismatch_pct, fit_pct, rmse}``; ``outputs[experiment][model]``
    the simulated output (time, n_y).
    """

    rows: list[dict]
    experiments: dict[str, Record]
    outputs: dict[str, dict[str, torch.Tensor]] = field(repr=False)

    def fit(self, experiment: str, model: str) -> float:
        """The fit % of ``model`` on ``experiment``."""
        return next(r["fit_pct"] for r in self.rows if (r["experiment"], r["model"]) == (experiment, model))


def compare(
    models: dict[str, Callable[..., torch.Tensor]],
    experiments: Record | list[Record],
    **simulate_options,
) -> Comparison:
    """Simulate every model on every experiment and score it (module docstring).

    Args:
        models: label -> a physics model or any callable ``model(t, u) -> y`` (batch, time, n_y).
        experiments: one record or several (names must differ).
        simulate_options: forwarded to the models (e.g. ``solver=Dopri5()``, :func:`~torchpaml.simulate`).
    """
    records = [experiments] if isinstance(experiments, Record) else list(experiments)
    names = [r.name for r in records]
    if len(set(names)) != len(names):
        raise ConfigurationError(f"experiment names must differ to be told apart in the comparison, got {names}")
    rows, outputs = [], {}
    for record in records:
        t, u, y = record.batch()
        outputs[record.name] = {}
        for label, model in models.items():
            with torch.no_grad():
                y_model = model(t - t[0], u, **simulate_options)
            outputs[record.name][label] = y_model[0]
            rows.append({
                "experiment": record.name, "model": label, "mismatch_pct": 100 * mismatch(y, y_model),
                "fit_pct": fit_percent(y, y_model), "rmse": rmse(y, y_model),
            })
    return Comparison(rows, {r.name: r for r in records}, outputs)
