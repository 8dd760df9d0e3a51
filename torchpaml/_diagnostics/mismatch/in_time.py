r"""Where in time a model's error sits: concentrated at the start (a wrong initial state), or growing (drift).

Over the validation records $e = y - \hat y$, each record's samples split into its first :data:`START` share, the
rest's first half and its last half:

* ``start_share``: the share of the squared error in the starts, $\sum_{\text{start}} e^2 / \sum e^2$; an error
  spread evenly in time gives :data:`START`;
* ``growth``: the RMS of $e$ over the last halves over that over the first halves (the starts left out); an error
  that does not drift gives about 1.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from torchpaml._data import Record

__all__ = ["START", "ErrorInTime", "error_in_time"]

#: The share of each record that counts as its start.
START = 0.1
#: A start share this many times :data:`START` is called concentrated at the start; a growth above it, drift.
MARKED = 2.0


@dataclass(frozen=True)
class ErrorInTime:
    """Where in time the error sits (module docstring)."""

    start_share: float
    growth: float

    def describe(self) -> str:
        """One sentence: the figures, and what they point at."""
        figures = (f"the first {100 * START:.0f} % of each record carries {100 * self.start_share:.0f} % of the squared "
                   f"error; its RMS over the last half is {self.growth:.2f}x that over the first")
        if self.start_share > MARKED * START:
            return f"{figures}: concentrated at the start (the initial state)"
        if self.growth > MARKED:
            return f"{figures}: it grows (drift)"
        return f"{figures}: spread evenly in time"


def error_in_time(records: Sequence[Record], outputs: Sequence[torch.Tensor]) -> ErrorInTime:
    """Where in time the error of ``outputs`` (each (time, n_y), the model's on each record) sits on ``records``."""
    start = first = last = total = 0.0
    n_first = n_last = 0
    for record, output in zip(records, outputs, strict=True):
        squared = (record.y - output.reshape(record.y.shape)).square().sum(-1)
        cut = max(1, round(START * len(squared)))
        half = cut + (len(squared) - cut) // 2
        start += float(squared[:cut].sum())
        first, n_first = first + float(squared[cut:half].sum()), n_first + half - cut
        last, n_last = last + float(squared[half:].sum()), n_last + len(squared) - half
        total += float(squared.sum())
    share = start / total if total > 0 else START
    growth = (last / max(n_last, 1)) ** 0.5 / (first / n_first) ** 0.5 if first > 0 and n_first else 1.0
    return ErrorInTime(share, growth)
