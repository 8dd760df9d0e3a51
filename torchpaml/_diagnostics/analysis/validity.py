r"""Where the physics holds: its error binned by signal amplitude, and over a grid of sine tests.

* :func:`error_by_amplitude`: the samples of one record grouped by $|u|$ (or $|y|$) into bins, and the
  mismatch $\|y - \hat y\|/\|y\|$ inside each bin. A physics that is right for small signals and wrong
  for large ones shows a mismatch that grows across the bins.
* :func:`validity_map`: sine tests $\alpha\sin\omega t$ over amplitude × frequency, the mismatch of the
  physics in each cell (the caller supplies the measurements of each test), and a heat map.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._data import Record
from torchpaml._metrics import mismatch

__all__ = ["AmplitudeBins", "error_by_amplitude", "ValidityMap", "validity_map"]


@dataclass
class AmplitudeBins:
    """Bin edges (B + 1,) of |signal|, and per bin the sample count and the mismatch (fraction; NaN if empty)."""

    edges: np.ndarray
    counts: np.ndarray
    mismatch: np.ndarray


def error_by_amplitude(signal, y, y_model, bins: int = 5) -> AmplitudeBins:
    """Mismatch of ``y_model`` within bins of equal width in |``signal``| (the input u or the output y)."""
    s, y, y_model = (np.asarray(torch.as_tensor(v).detach().reshape(-1)) for v in (signal, y, y_model))
    edges = np.linspace(0.0, float(np.abs(s).max()), bins + 1)
    index = np.clip(np.digitize(np.abs(s), edges[1:-1]), 0, bins - 1)
    counts = np.bincount(index, minlength=bins)
    errors = np.bincount(index, weights=(y - y_model) ** 2, minlength=bins)
    energy = np.bincount(index, weights=y**2, minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        return AmplitudeBins(edges, counts, np.sqrt(errors / energy))


@dataclass
class ValidityMap:
    """Mismatch (fraction) of the physics per sine test: ``mismatch[i, j]`` at ``amplitudes[i]``, ``frequencies[j]``."""

    amplitudes: np.ndarray
    frequencies: np.ndarray
    mismatch: np.ndarray


def validity_map(
    physics: AbstractPhysics,
    measure: Callable[[float, float], Record],
    amplitudes: list[float],
    frequencies: list[float],
    **simulate_options,
) -> ValidityMap:
    """The physics' mismatch on ``measure(amplitude, omega)``, one measured sine test per cell."""
    table = np.zeros((len(amplitudes), len(frequencies)))
    for i, amplitude in enumerate(amplitudes):
        for j, omega in enumerate(frequencies):
            t, u, y = measure(amplitude, omega).batch()
            with torch.no_grad():
                table[i, j] = mismatch(y, physics(t - t[0], u, **simulate_options))
    return ValidityMap(np.asarray(amplitudes, float), np.asarray(frequencies, float), table)
