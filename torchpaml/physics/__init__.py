"""Physics models as ``nn.Module``s with named, constrained physical parameters."""

from torchpaml.physics.base import AbstractPhysics, SecondOrderPhysics
from torchpaml.physics.oscillator import Oscillator
from torchpaml.physics.pendulum import Pendulum

__all__ = ["AbstractPhysics", "SecondOrderPhysics", "Oscillator", "Pendulum"]
