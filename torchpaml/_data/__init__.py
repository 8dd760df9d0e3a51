"""Data, above the simulator: records (:class:`Record`), where they come from (files, simulation), and a record
through the simulator (:mod:`~torchpaml._data.simulation`).

Making data imports neither Lightning nor the trainer.
"""

from torchpaml._data.record import Record
from torchpaml._data.simulation import simulate_record
from torchpaml._data.sources import RecordSource, Files, Simulated

#: The earlier names of :class:`Record` and :class:`RecordSource`, kept so that users' code and configs still run.
Experiment, ExperimentSource = Record, RecordSource

__all__ = ["Experiment", "ExperimentSource", "Record", "RecordSource", "Files", "Simulated", "simulate_record"]
