r"""A fitted model's prediction on a record: its outputs and states from the initial state its policy gives, and an
output band from the fit's covariance.

**The start.** The model's initial-state policy (:class:`~torchpaml.FittedModel`'s ``initial_state``, the one the
diagnosis scored with) starts the record: ``Rest()`` at rest; ``Estimate()`` at the state that best explains the
outputs of the record's start window, the parameters fixed (:func:`~torchpaml.estimate_initial_state`,
:func:`~torchpaml._fit.initial_state.start_window`).

**The band.** To first order in the parameters $\theta$ (those the fit estimated), with the output's sensitivity
$J_k = \partial \hat y_k / \partial \theta$ (time, n_y, p) and the fit's covariance
$\Sigma = D\,R\,D$ ($D$ the standard errors, $R$ their correlation), the output's standard error is
$s_k = \sqrt{\operatorname{diag}(J_k \Sigma J_k^\top)}$ and the band is $\hat y_k \pm z\,s_k$, $z$ the normal
quantile of ``level`` (1.96 at 95 %). It is the parameters' uncertainty only: the noise of the measurement and
the error of the model class are not in it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import torch

from torchpaml._data import Record
from torchpaml._data.simulation import record_jacobian
from torchpaml._errors import ConfigurationError, DataError
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._fit.physics_fit import estimate_initial_state
from torchpaml._fit.uncertainty import constraint_slopes
from torchpaml._physics.checks import check_channels as check_physics_channels
from torchpaml._simulate.solvers import Auto

__all__ = ["Prediction", "check_channels", "initial_state_of", "output_std", "predict"]


@dataclass(frozen=True)
class Prediction:
    """A model's prediction on one record (module docstring).

    Attributes:
        y: the output, (time, n_y).
        states: the states, (time, n_state).
        x0: the initial state it started from, (n_state,).
        lower, upper: the output band at ``level``, (time, n_y) each; ``None`` where no band was asked for.
        level: the band's coverage (0.95), or ``None``.
    """

    y: torch.Tensor
    states: torch.Tensor
    x0: torch.Tensor
    lower: torch.Tensor | None = None
    upper: torch.Tensor | None = None
    level: float | None = None


def check_channels(model: FittedModel, record: Record) -> None:
    """Refuse ``record`` where its channels are not the model's: the library's record check
    (:func:`~torchpaml._physics.checks.check_channels`: the inputs and outputs by count, and by name where the physics
    names them), then the names the model was fitted on, where both the model and the record name them."""
    check_physics_channels(model.physics, record, missing=True)
    for what, names, given in (("inputs", model.inputs, record.input_names),
                               ("outputs", model.outputs, record.output_names)):
        declared = what in record.metadata or what == "inputs"  # a record's default output name says nothing
        if names and declared and given != list(names):
            raise DataError(f"record {record.name!r} names its {what} {given}; the model was fitted on {list(names)}: "
                            "rename the columns, or declare them in the file's metadata line")


def initial_state_of(model: FittedModel, record: Record) -> torch.Tensor:
    """The state (n_state,) the model's policy starts ``record`` from (module docstring)."""
    if model.initial_state.estimated and record.metadata.get("outputs_missing"):
        raise DataError(f"the model starts each record from the state that best explains its outputs (initial_state "
                        f"{model.initial_state.name!r}), and {record.name!r} has no output columns: add them")
    start = model.initial_state.validation_starts(
        [record], lambda r: estimate_initial_state(model.physics, r, solver=Auto(start=model.solver)))[0]
    return model.physics.initial_state(1)[0] if start is None else start.reshape(-1)


def output_std(model: FittedModel, record: Record, x0: torch.Tensor) -> torch.Tensor:
    r"""$s_k$ (module docstring), (time, n_y). Raises :class:`~torchpaml.ConfigurationError` where the model has no
    uncertainty or the fit did not determine a parameter."""
    if model.uncertainty is None:
        raise ConfigurationError("the model carries no parameter uncertainty (it was not saved from a fit); predict "
                                 "without a band")
    std = model.uncertainty.std
    names = [name for name in std if name in model.physics.physical_parameters()]
    undetermined = [name for name in names if not math.isfinite(std[name])]
    if undetermined:
        raise ConfigurationError(f"the fit did not determine {undetermined} (infinite standard error): the band would "
                                 "be unbounded; fix those parameters and fit again, or predict without a band")
    if not names:
        return torch.zeros_like(record.y)
    order = list(std)
    index = torch.tensor([order.index(name) for name in names])
    deviation = torch.tensor([std[name] for name in names], dtype=torch.float64)
    covariance = deviation[:, None] * model.uncertainty.correlation[index][:, index] * deviation[None, :]
    _, J = record_jacobian(model.physics, names, record, x0, solver=model.solver)
    J = J[0] / constraint_slopes(model.physics, names)  # d y / d theta, (time, n_y, p)
    return torch.einsum("typ,pq,tyq->ty", J, covariance, J).clamp(min=0.0).sqrt()


def predict(model: FittedModel, record: Record, level: float | None = None) -> Prediction:
    """``model`` on ``record``: outputs and states from the policy's initial state, and with ``level`` (e.g. 0.95) the
    output band from the fit's covariance (module docstring)."""
    check_channels(model, record)
    if level is not None and not 0.0 < level < 1.0:
        raise ConfigurationError(f"the band's level is a coverage between 0 and 1 (0.95), got {level}")
    x0 = initial_state_of(model, record)
    y = model.simulate(record, x0)
    states = model.states(record, x0)
    if level is None:
        return Prediction(y, states, x0)
    half = NormalDist().inv_cdf(0.5 + level / 2) * output_std(model, record, x0)
    return Prediction(y, states, x0, y - half, y + half, level)
