"""Data, above the simulator: records (:class:`Experiment`), where they come from (files, simulation), and a record
through the simulator (:mod:`~torchpaml._data.simulation`).

Making data imports neither Lightning nor the trainer.
"""

from torchpaml._data.experiment import Experiment
from torchpaml._data.simulation import simulate_record
from torchpaml._data.sources import ExperimentSource, Files, Simulated

__all__ = ["Experiment", "ExperimentSource", "Files", "Simulated", "simulate_record"]
