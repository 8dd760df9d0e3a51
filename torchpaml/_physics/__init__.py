"""Physics models as ``nn.Module``s with named, constrained physical parameters, and effects to add to them."""

from torchpaml._physics import effects
from torchpaml._physics.base import AbstractPhysics, SecondOrderPhysics, complete_state, state_vector
from torchpaml._physics.composed import ComposedModel, compose
from torchpaml._physics.discovered import DiscoveredForce
from torchpaml._physics.effects import *  # noqa: F403  the library's effects: effects.__all__, derived from EFFECTS
from torchpaml._physics.oscillator import Oscillator
from torchpaml._physics.pendulum import Pendulum
from torchpaml._physics.terms import TermLibrary

__all__ = ["AbstractPhysics", "ComposedModel", "DiscoveredForce", "Oscillator", "Pendulum", "SecondOrderPhysics",
           "TermLibrary", "complete_state", "compose", "state_vector", *effects.__all__]
