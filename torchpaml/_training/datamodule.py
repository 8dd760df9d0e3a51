r"""A ``LightningDataModule`` over experiments: whole records, or windows of them with a washout.

A batch is a dict ``{"t": (time,), "u": (batch, time, 1), "y": (batch, time, 1), "washout": int}``;
every record in a batch shares the time grid (relative to its first sample). With ``window``, each
record is cut into windows of ``window`` seconds, each preceded by ``washout`` seconds of the record
itself: the models start at rest at the beginning of the washout, and the loss and metrics skip the
washout samples, so the unknown state at the window's start has decayed by the time the loss
counts (for a damped system, choose ``washout`` a few time constants long). Windows assume
time-invariant physics (time restarts at 0 in each window).

Under a distributed strategy (DDP), Lightning's distributed sampler gives each process its share
of the records or windows.
"""

from __future__ import annotations

import lightning as L
import torch
from torch.utils.data import DataLoader

from torchpaml._data import Record
from torchpaml._errors import ConfigurationError, DataError
from torchpaml._data.sources import RecordSource

__all__ = ["RecordDataModule", "collate"]

SPLITS = ("identification", "train", "validation", "test")


def collate(items: list[dict]) -> dict:
    """Stack records that share a time grid into one batch (see the module docstring)."""
    first = items[0]
    for item in items[1:]:
        if len(item["t"]) != len(first["t"]) or not torch.allclose(item["t"], first["t"]):
            raise DataError(
                f"records {first['name']!r} and {item['name']!r} have different time grids and cannot share a "
                "batch; set batch_size: 1, or cut them into equal windows (window: SECONDS)"
            )
    return {
        "t": first["t"],
        "u": torch.stack([item["u"] for item in items]),
        "y": torch.stack([item["y"] for item in items]),
        "washout": first["washout"],
        "names": [item["name"] for item in items],
    }


class RecordDataModule(L.LightningDataModule):
    """Experiments for the four roles a two-stage fit needs.

    Args:
        train: the records the current stage is fitted on.
        validation: records for validation metrics and figures (optional).
        test: records for ``torchpaml test`` (optional).
        identification: the physics-identification records (the paper's sine); stage 2 fits the
            physics on them when it is not given a stage-1 checkpoint, and re-estimates θ on
            them for the first-order check Δθ.
        window: cut records into windows of this many seconds (default: whole records).
        washout: seconds before each window that are simulated but not scored.
        batch_size: records or windows per batch (default: all of them, i.e. full-batch training).
    """

    def __init__(
        self,
        train: RecordSource,
        validation: RecordSource | None = None,
        test: RecordSource | None = None,
        identification: RecordSource | None = None,
        window: float | None = None,
        washout: float = 0.0,
        batch_size: int | None = None,
    ):
        super().__init__()
        if window is not None and not window > 0 or washout < 0:
            raise ConfigurationError(f"need window > 0 and washout >= 0, got window={window}, washout={washout}")
        self.sources = {"identification": identification, "train": train, "validation": validation, "test": test}
        self.window, self.washout, self.batch_size = window, washout, batch_size
        self._records: dict[str, list[Record]] = {}

    def records(self, split: str) -> list[Record]:
        """The records of ``split`` (loaded once); empty if the split has no source."""
        if split not in SPLITS:
            raise ConfigurationError(f"unknown split {split!r}; use one of {SPLITS}")
        if split not in self._records:
            source = self.sources[split]
            records = [] if source is None else source.experiments()
            held = [r.name for r in records if r.hold != "foh"]
            if held:
                raise DataError(f"experiment(s) {held} hold their input constant between samples (hold='zoh'), but "
                                "the Lightning systems simulate the input linear between samples; diagnose or fit "
                                "them with torchpaml diagnose / fit_physics, which take either hold")
            self._records[split] = records
        return self._records[split]

    def items(self, split: str, windows: bool = True) -> list[dict]:
        """Records of ``split`` as batch items, cut into windows if the module has a ``window`` and ``windows``."""
        items = []
        for record in self.records(split):
            cuts = self._cuts(record) if windows else [(0, 0, len(record.t))]
            for start, skip, stop in cuts:
                t = record.t[start:stop]
                items.append(
                    {"t": t - t[0], "u": record.u[start:stop], "y": record.y[start:stop], "washout": skip,
                     "name": record.name}
                )
        return items

    def _cuts(self, record: Record) -> list[tuple[int, int, int]]:
        """(first simulated sample, samples to skip, end) for each window of ``record``."""
        if self.window is None:
            return [(0, 0, len(record.t))]
        dt = record.dt
        length, skip = round(self.window / dt), round(self.washout / dt)
        if length + skip > len(record.t):
            raise DataError(
                f"record {record.name!r} lasts {len(record.t) * dt:g} s, shorter than window + washout = "
                f"{self.window + self.washout:g} s; shorten the window or the washout"
            )
        return [(begin - skip, skip, begin + length) for begin in range(skip, len(record.t) - length + 1, length)]

    def full_batch(self, split: str) -> dict | None:
        """All of ``split``, whole records, in one batch (identification fit, figures); ``None`` if empty."""
        items = self.items(split, windows=False)
        return collate(items) if items else None

    def _loader(self, split: str, shuffle: bool = False) -> DataLoader:
        items = self.items(split)
        if not items:
            raise DataError(f"the {split} split is empty; give the data module a {split} source")
        return DataLoader(items, batch_size=self.batch_size or len(items), shuffle=shuffle, collate_fn=collate)

    def train_dataloader(self) -> DataLoader:
        return self._loader("train")

    def val_dataloader(self) -> DataLoader:
        return self._loader("validation") if self.sources["validation"] is not None else []

    def test_dataloader(self) -> DataLoader:
        return self._loader("test")
