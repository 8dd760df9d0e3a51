"""The paper's "true" system: a damped, driven pendulum observed through its horizontal position."""

from __future__ import annotations

import torch

from torchpaml._parameters import register_parameters
from torchpaml._physics.base import SecondOrderPhysics
from torchpaml._physics.oscillator import damped_parameters

__all__ = ["Pendulum"]


class Pendulum(SecondOrderPhysics):
    r"""$\ddot x + 2\zeta\omega_0\dot x + \omega_0^2 \sin x = g\,u$, output $y = \sin x$.

    State (batch, 2) = (angle from the lower equilibrium in rad, angular velocity in rad/s). Its
    small-signal linearisation is :class:`~torchpaml.Oscillator`. A constant torque $u_0$ has
    an equilibrium only for $|g u_0| \le \omega_0^2$; beyond it the pendulum swings over the top.
    """

    def __init__(self, zeta: float = 0.5, omega0: float = 2.0, gain: float = 1.0, *, learn=("zeta",)):
        super().__init__()
        register_parameters(self, damped_parameters(zeta, omega0, gain, "small-signal natural frequency"), tuple(learn))

    def acceleration(self, t, x, v, u):
        return self.gain * u - 2 * self.zeta * self.omega0 * v - self.omega0**2 * torch.sin(x)

    def output(self, x, u):
        return torch.sin(x[..., :1])
