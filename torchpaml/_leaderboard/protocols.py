r"""The benchmarks' protocol numerics, usable on any record: the noise floor of a record whose input repeats, a
periodic input applied twice (its second period is the steady state), and a fitted model refitted with one of its
effects replaced."""

from __future__ import annotations

import copy
import math

import torch

from torchpaml._data import Record
from torchpaml._diagnostics.analysis.noise_floor import RUN_WINDOW, repeated_runs, settled_differences

__all__ = ["noise_floor", "periodic_twice", "with_effect"]


def noise_floor(record: Record, period: int, window: int = RUN_WINDOW) -> tuple[float, int]:
    r"""The output noise's RMS (the data's unit) where ``record``'s input repeats at lag ``period``, and how many
    samples it rests on: over the runs of repeats (:func:`~torchpaml._diagnostics.analysis.noise_floor.repeated_runs`:
    $u_k \approx u_{k+P}$ over ``window`` samples), once the response has settled (each run's second half),
    $y_k - y_{k+P}$ is the difference of two noise samples, so the floor is its RMS over $\sqrt 2$:
    the diagnosis' reading from runs of repeats, at a given lag. Raises ``ValueError`` where the input never
    repeats."""
    runs = repeated_runs(record.u, period, window)
    if not runs:
        raise ValueError(f"the input of {record.name!r} does not repeat at lag {period} over {2 * window} samples: "
                         "no noise floor can be read from it")
    differences = settled_differences(record.y[:, 0].detach().to(torch.float64), runs, period)
    return float(differences.square().mean().sqrt()) / math.sqrt(2), len(differences)


def periodic_twice(record: Record) -> Record:
    """One period of a periodic record, applied twice (its output repeated): the second is the steady state."""
    n = len(record.t)
    return Record(torch.cat([record.t, record.t + n * record.dt]), torch.cat([record.u, record.u]),
                  torch.cat([record.y, record.y]), name=record.name)


def with_effect(model, effect):
    """A copy of the composed ``model`` with its effect of ``effect``'s name replaced by ``effect``, in its place
    among the others (a bound changed, a shape freed)."""
    copied = copy.deepcopy(model)
    effects = dict(copied.effects)
    if effect.name not in effects:
        raise ValueError(f"{model.display_name} has no effect {effect.name!r}; it has {sorted(effects)}")
    effects[effect.name] = effect
    replaced = copied.without_effects()
    for each in effects.values():
        replaced = replaced + each
    return replaced
