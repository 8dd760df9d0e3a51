"""Lightning training: thin systems over the library's plain modules, a data module, and the CLI."""

from torchpaml.training.datamodule import ExperimentDataModule
from torchpaml.training.joint_fit import JointFit
from torchpaml.training.physics_fit import PhysicsFit
from torchpaml.training.residual_fit import ResidualFit
from torchpaml.data.sources import ExperimentSource, Files, Simulated  # re-exported: configs name them here too
from torchpaml.training.system import HybridSystem

__all__ = [
    "ExperimentDataModule",
    "ExperimentSource",
    "Files",
    "HybridSystem",
    "JointFit",
    "PhysicsFit",
    "ResidualFit",
    "Simulated",
]
