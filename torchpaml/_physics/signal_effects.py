r"""Effects on the measured signals: the sensor's dynamics and static maps, and the actuator's static map.

==================== ======================================================================== ===================
name                 term                                                                     parameters (start)
==================== ======================================================================== ===================
sensor_lag           $y = y_\ell$, $\dot y_\ell = (h(x, u) - y_\ell)/\tau$ (a first-order sensor; $y = h$ at $\tau = 0$)   tau (0)
magnitude_sensor     $y = h + m\,(|h| - h)$: at $m = 1$ the sensor reads only the magnitude   m (0)
quadratic_sensor     $y = h + a\,h^2$: a calibration curve bent to one side                    a (0)
quadratic_input      $\tilde u = u + b\,u^2$: an actuator whose gain differs with the sign of u   b (0)
==================== ======================================================================== ===================

Each is off at zero strength, so the ranking scores it like any effect (:func:`~torchpaml.rank_missing_effects`).
The sensor effects act on physics with one output, the input map on physics with one input. A sensor lag reads
the base's output map $h(x, u)$ with the measured input (before any input map of another effect), and replaces the
output after the output maps added before it. On linear physics a sensor lag and an actuator lag
(:class:`~torchpaml.InputLag`) give the same output: linear filters commute, so no measurement of u and y tells
them apart; the ranking then names whichever scores higher.
"""

from __future__ import annotations

import math

import torch

from torchpaml._parameters import PhysicalParameter, Real, register_parameters
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effect import AbstractEffect, EffectState
from torchpaml._physics.memory_effects import sample_interval

__all__ = ["MagnitudeSensor", "QuadraticInput", "QuadraticSensor", "SensorLag"]


def _one_output(name: str, physics: AbstractPhysics) -> str | None:
    if physics.output_dim != 1:
        return f"{name} acts on a single output; {physics.display_name} has {physics.output_dim}"
    return None


class SensorLag(AbstractEffect):
    r"""A sensor that lags the quantity it measures: $\dot y_\ell = (h(x, u) - y_\ell)/\tau$, $y = y_\ell$
    ($\tau > 0$), $y = h$ ($\tau = 0$).

    ``tau`` (s, >= 0) is the strength; its first-order direction, $-\tau\dot h$, is probed at one sample interval
    (:meth:`probe`), as :class:`~torchpaml.InputLag`'s. For physics with one output. State ``y_lag`` in [y],
    starting at 0 (rest).
    """

    name = "sensor_lag"
    equation = "y = y_lag, y_lag' = (h(x, u) - y_lag)/tau"
    own_states = (EffectState("y_lag", "[y]", 0.0, "lagged sensor reading"),)

    def __init__(self, tau: float = 0.0, *, learn=("tau",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("tau", tau, "s", Real(), "sensor time constant",
                                                     physical=(0.0, math.inf))], learn)

    def applies_to(self, physics: AbstractPhysics):
        return _one_output(self.name, physics) or super().applies_to(physics)

    def probe(self, records):
        return sample_interval(records)

    def output_map(self, y, z=None):
        return torch.where(self.tau > 0, z, y)

    def state_rate(self, physics: AbstractPhysics, x, z, u):
        on = self.tau > 0
        return torch.where(on, (physics.output(x, u) - z) / torch.where(on, self.tau, 1.0), 0.0)


class MagnitudeSensor(AbstractEffect):
    r"""A sensor blind to the sign for a share $m$ of its reading, $y = h + m\,(|h| - h)$: at $m = 1$ it reads
    $|h|$ (a speed counter that does not see the direction). ``m`` (dimensionless, in [0, 1]) is the strength."""

    name, equation = "magnitude_sensor", "y -> y + m*(|y| - y)"

    def __init__(self, m: float = 0.0, *, learn=("m",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("m", m, "-", Real(), "share of the reading that is the magnitude",
                                                     physical=(0.0, 1.0))], learn)

    def applies_to(self, physics: AbstractPhysics):
        return _one_output(self.name, physics) or super().applies_to(physics)

    def output_map(self, y, z=None):
        return y + self.m * (y.abs() - y)


class QuadraticSensor(AbstractEffect):
    r"""A sensor's calibration curve bent to one side, $y = h + a\,h^2$. ``a`` (1/[y]) is the strength."""

    name, equation = "quadratic_sensor", "y -> y + a*y^2"

    def __init__(self, a: float = 0.0, *, learn=("a",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("a", a, "1/[y]", Real(), "quadratic sensor coefficient")], learn)

    def applies_to(self, physics: AbstractPhysics):
        return _one_output(self.name, physics) or super().applies_to(physics)

    def output_map(self, y, z=None):
        return y + self.a * y * y


class QuadraticInput(AbstractEffect):
    r"""An actuator whose gain differs with the sign of the command, $\tilde u = u + b\,u^2$. ``b`` (1/[u]) is the
    strength. For physics with one input."""

    name, equation = "quadratic_input", "u -> u + b*u^2"

    def __init__(self, b: float = 0.0, *, learn=("b",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("b", b, "1/[u]", Real(), "quadratic input coefficient")], learn)

    def applies_to(self, physics: AbstractPhysics):
        if physics.input_dim != 1:
            return f"{self.name} maps a single input; {physics.display_name} has {physics.input_dim}"
        return super().applies_to(physics)

    def input_map(self, u, z=None):
        return u + self.b * u * u
