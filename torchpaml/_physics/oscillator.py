"""The paper's linearised physics: a damped, driven harmonic oscillator."""

from __future__ import annotations

import torch

from torchpaml._parameters import PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics.base import SecondOrderPhysics

__all__ = ["Oscillator", "damped_parameters"]


def damped_parameters(zeta: float, omega0: float, gain: float, frequency_meaning: str) -> list[PhysicalParameter]:
    """The declarations (ζ, ω0, g) shared by the damped second-order models."""
    return [
        PhysicalParameter("zeta", zeta, "-", Positive(), "damping ratio"),
        PhysicalParameter("omega0", omega0, "rad/s", Positive(), frequency_meaning),
        PhysicalParameter("gain", gain, "1/s^2", Real(), "input gain"),
    ]


class Oscillator(SecondOrderPhysics):
    r"""$\ddot x + 2\zeta\omega_0\dot x + \omega_0^2 x = g\,u$, output $y = x$.

    State (batch, 2) = (position, velocity). Linear, so :func:`~torchpaml.simulate` uses the exact
    first-order-hold discretisation by default.

    Args:
        zeta: damping ratio $\zeta > 0$.
        omega0: undamped natural frequency $\omega_0 > 0$ in rad/s.
        gain: input gain $g$ (output units per input unit times s^-2).
        learn: names of the parameters to learn; the others are fixed.
    """

    def __init__(self, zeta: float = 0.5, omega0: float = 2.0, gain: float = 1.0, *, learn=("zeta",)):
        super().__init__()
        register_parameters(self, damped_parameters(zeta, omega0, gain, "natural frequency"), tuple(learn))

    def acceleration(self, t, x, v, u):
        return self.gain * u - 2 * self.zeta * self.omega0 * v - self.omega0**2 * x

    def state_space(self):
        zero, one = torch.zeros((), dtype=torch.float64), torch.ones((), dtype=torch.float64)
        A = torch.stack([torch.stack([zero, one]), torch.stack([-self.omega0**2, -2 * self.zeta * self.omega0])])
        B = torch.stack([zero, self.gain]).reshape(2, 1)
        C = torch.tensor([[1.0, 0.0]], dtype=torch.float64)
        D = torch.zeros(1, 1, dtype=torch.float64)
        return A, B, C, D
