"""Data, below everything else: records (:class:`Experiment`) and where they come from (files, simulation).

Making data imports neither Lightning nor the trainer.
"""

from torchpaml._data.experiment import Experiment
from torchpaml._data.sources import ExperimentSource, Files, Simulated

__all__ = ["Experiment", "ExperimentSource", "Files", "Simulated"]
