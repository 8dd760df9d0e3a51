"""Lightning training: thin systems over the library's plain modules, a data module, and the CLI."""

from torchpaml._training.datamodule import RecordDataModule
from torchpaml._training.joint_fit import JointFit
from torchpaml._training.physics_fit import PhysicsFit
from torchpaml._training.residual_fit import ResidualFit
from torchpaml._data.sources import RecordSource, Files, Simulated  # re-exported: configs name them here too
from torchpaml._training.system import HybridSystem

#: The earlier names of :class:`RecordDataModule` and :class:`RecordSource`, kept for users' configs.
ExperimentDataModule, ExperimentSource = RecordDataModule, RecordSource

__all__ = [
    "ExperimentDataModule",
    "ExperimentSource",
    "RecordDataModule",
    "RecordSource",
    "Files",
    "HybridSystem",
    "JointFit",
    "PhysicsFit",
    "ResidualFit",
    "Simulated",
]
