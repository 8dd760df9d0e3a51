r"""Effects on the measured signals: the sensor's dynamics and static maps, and the actuator's static map.

==================== ======================================================================== ===================
name                 term                                                                     parameters (start)
==================== ======================================================================== ===================
sensor_lag           $y = y_\ell$, $\dot y_\ell = (h(x, u) - y_\ell)/\tau$ (a first-order sensor; $y = h$ at $\tau = 0$)   tau (0)
magnitude_sensor     $y = h + m\,(|h| - h)$: at $m = 1$ the sensor reads only the magnitude   m (0)
quadratic_sensor     $y = h + a\,h^2$: a calibration curve bent to one side                    a (0)
quadratic_input      $\tilde u = u + b\,u^2$: an actuator whose gain differs with the sign of u   b (0)
feedthrough          $y = h + d\,u$: a direct path from the input to the sensor                 d (0)
extra_mode           $y = h + q$, $\ddot q = g\,u - 2\zeta_m\omega_m\dot q - \omega_m^2 q$: one more linear mode   g (0), omega_m, zeta_m
==================== ======================================================================== ===================

Each is off at zero strength, so the ranking scores it like any effect (:func:`~torchpaml.rank_missing_effects`).
The sensor effects act on physics with one output, the input map on physics with one input, the feedthrough on
physics with one of each. A sensor lag reads
the base's output map $h(x, u)$ with the measured input (before any input map of another effect), and replaces the
output after the output maps added before it. On linear physics a sensor lag and an actuator lag
(:class:`~torchpaml.InputLag`) give the same output: linear filters commute, so no measurement of u and y tells
them apart; the ranking then names whichever scores higher.
"""

from __future__ import annotations

import math

import torch

from torchpaml._parameters import PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effect import AbstractEffect, EffectState
from torchpaml._physics.memory_effects import sample_interval

__all__ = ["ExtraMode", "Feedthrough", "MagnitudeSensor", "QuadraticInput", "QuadraticSensor", "SensorLag"]


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
    $|h|$ (a speed counter that does not see the direction). ``m`` (dimensionless, in [0, 1]) is the strength.

    At $m = 1$ a linear physics fitted to the reading has almost no gain (the magnitude of a response to a zero-mean
    input hardly correlates with the input), and the first-order direction of $m$ at 0 sees nothing: the probes also
    refit it from $m = 1$ on the physics alone (``far_strength``)."""

    name, equation = "magnitude_sensor", "y -> y + m*(|y| - y)"
    far_strength = 1.0

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
    generic = True  # a place more than physics: the simpler-effect rule (ranking.occam)

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
    generic = True  # a place more than physics: the simpler-effect rule (ranking.occam)

    def __init__(self, b: float = 0.0, *, learn=("b",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("b", b, "1/[u]", Real(), "quadratic input coefficient")], learn)

    def applies_to(self, physics: AbstractPhysics):
        if physics.input_dim != 1:
            return f"{self.name} maps a single input; {physics.display_name} has {physics.input_dim}"
        return super().applies_to(physics)

    def input_map(self, u, z=None):
        return u + self.b * u * u


class Feedthrough(AbstractEffect):
    r"""A direct path from the input to the sensor, $y = h(x, u) + d\,u$: a measurement that picks up part of the
    drive (crosstalk in an electronic circuit, a sensor mounted on the actuator), or dynamics far faster than the
    samples that pass the input through. ``d`` ([y]/[u]) is the strength. For physics with one input and one
    output (on Silverbox the ladder adds it, ``d`` = -0.0366 V/V)."""

    name, equation = "feedthrough", "y -> y + d*u"
    reads_input = True

    def __init__(self, d: float = 0.0, *, learn=("d",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("d", d, "[y]/[u]", Real(), "direct gain from input to output")],
                            learn)

    def applies_to(self, physics: AbstractPhysics):
        if physics.input_dim != 1:
            return f"{self.name} passes a single input; {physics.display_name} has {physics.input_dim}"
        return _one_output(self.name, physics) or super().applies_to(physics)

    def output_map(self, y, z=None, u=None):
        return y + self.d * u[..., :1, :]


#: The extra mode's damping ratio at its starts: broad enough that a start near the mode's frequency sees it.
MODE_DAMPING = 0.3
#: The least damping ratio of the extra mode while the ranking refits it (:meth:`ExtraMode.bounds`).
MIN_DAMPING = 1e-3


class ExtraMode(AbstractEffect):
    r"""One more linear mode of the device, driven by the input and seen at the output (a structural resonance, a
    second mass the physics leaves out):

    $$ \ddot q = g\,u - 2\zeta_m\omega_m\dot q - \omega_m^2 q, \qquad y = h(x, u) + q. $$

    ``g`` ([y]/([u] s^2)) is the strength; ``omega_m`` (rad/s) and ``zeta_m`` are learned with it. Its frequency is
    not known in advance: the ranking screens starts spread over the frequencies the records resolve
    (:meth:`starts`). For physics with one input and one output. States ``q`` and ``q_dot``, starting at rest.
    """

    name = "extra_mode"
    generic = True  # a place more than physics: the simpler-effect rule (ranking.occam)
    equation = "y = h + q, q'' = g*u - 2*zeta_m*omega_m*q' - omega_m^2*q"
    own_states = (EffectState("q", "[y]", 0.0, "the mode's deflection at the output"),
                  EffectState("q_dot", "[y]/s", 0.0, "its rate"))

    def __init__(self, g: float = 0.0, omega_m: float = 1.0, zeta_m: float = MODE_DAMPING, *,
                 learn=("g", "omega_m", "zeta_m")):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("g", g, "[y]/([u] s^2)", Real(), "the mode's input gain"),
            PhysicalParameter("omega_m", omega_m, "rad/s", Positive(), "the mode's natural frequency"),
            PhysicalParameter("zeta_m", zeta_m, "-", Positive(), "the mode's damping ratio"),
        ], learn)

    def applies_to(self, physics: AbstractPhysics):
        if physics.input_dim != 1:
            return f"{self.name} is driven by a single input; {physics.display_name} has {physics.input_dim}"
        return _one_output(self.name, physics) or super().applies_to(physics)

    def starts(self, records):
        """``omega_m`` at five frequencies spaced evenly in log between ten periods per record and a quarter of the
        Nyquist frequency, each at ``zeta_m`` = :data:`MODE_DAMPING`."""
        step = sample_interval(records)
        if step is None:
            return [{}]
        length = max(float(r.t[-1] - r.t[0]) for r in records)
        low, high = 20 * math.pi / length, math.pi / (4 * step)
        if not low < high:
            return [{}]
        return [{"omega_m": low * (high / low) ** (i / 4), "zeta_m": MODE_DAMPING} for i in range(5)]

    def bounds(self, records):
        r"""``omega_m`` up to the Nyquist frequency $\pi/h$ and ``zeta_m`` in [:data:`MIN_DAMPING`, 10]: a mode beyond
        the Nyquist frequency is one the samples do not resolve, and an undamped one rings forever after its start
        (measured on Silverbox's last rung: unbounded, a refit drove the mode to 1.08 times the Nyquist frequency and
        its damping to 2.6e-21, a direct path from the input in disguise)."""
        step = sample_interval(records)
        return {"zeta_m": (MIN_DAMPING, 10.0)} | ({} if step is None else {"omega_m": (0.0, math.pi / step)})

    def output_map(self, y, z=None):
        return y + z[..., :1, :]

    def state_rate(self, physics: AbstractPhysics, x, z, u):
        q, rate = z[..., 0], z[..., 1]
        acceleration = self.g * u[..., 0] - 2 * self.zeta_m * self.omega_m * rate - self.omega_m**2 * q
        return torch.stack([rate, acceleration], dim=-1)
