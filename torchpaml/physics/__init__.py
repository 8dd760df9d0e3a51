"""Physics models as ``nn.Module``s with named, constrained physical parameters, and effects to add to them."""

from torchpaml.physics.base import AbstractPhysics, SecondOrderPhysics, state_vector
from torchpaml.physics.composed import ComposedModel, compose
from torchpaml.physics.discovered import DiscoveredForce, candidate_terms
from torchpaml.physics.effects import (
    EFFECTS,
    AbstractEffect,
    ConstantForce,
    CoulombFriction,
    CubicStiffness,
    DeadZone,
    InputSaturation,
    OutputSaturation,
    PendulumRestoring,
    QuadraticDamping,
    QuadraticStiffness,
    default_effects,
)
from torchpaml.physics.oscillator import Oscillator
from torchpaml.physics.pendulum import Pendulum

__all__ = [
    "AbstractPhysics",
    "SecondOrderPhysics",
    "state_vector",
    "Oscillator",
    "Pendulum",
    "AbstractEffect",
    "ComposedModel",
    "compose",
    "EFFECTS",
    "default_effects",
    "CubicStiffness",
    "QuadraticStiffness",
    "PendulumRestoring",
    "CoulombFriction",
    "QuadraticDamping",
    "ConstantForce",
    "InputSaturation",
    "OutputSaturation",
    "DeadZone",
    "DiscoveredForce",
    "candidate_terms",
]
