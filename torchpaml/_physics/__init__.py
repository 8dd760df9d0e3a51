"""Physics models as ``nn.Module``s with named, constrained physical parameters, and effects to add to them."""

from torchpaml._physics.base import AbstractPhysics, SecondOrderPhysics, complete_state, state_vector
from torchpaml._physics.composed import ComposedModel, compose
from torchpaml._physics.discovered import DiscoveredForce
from torchpaml._physics.terms import TermLibrary
from torchpaml._physics.effects import (
    EFFECTS,
    AbstractEffect,
    ConstantForce,
    CoulombFriction,
    CubicStiffness,
    DeadZone,
    DynamicFriction,
    EffectState,
    Hysteresis,
    InputLag,
    InputSaturation,
    OutputSaturation,
    PendulumRestoring,
    QuadraticDamping,
    QuadraticStiffness,
    default_effects,
)
from torchpaml._physics.oscillator import Oscillator
from torchpaml._physics.pendulum import Pendulum

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
    "Hysteresis",
    "DynamicFriction",
    "InputLag",
    "EffectState",
    "complete_state",
    "DiscoveredForce",
    "TermLibrary",
]
