r"""A user's linear physics, written as a user would: a mass on a spring and a damper, driven by a force.

$$ m\,\ddot y + c\,\dot y + k\,y = u, $$

with $u$ the force in N and $y$ the displacement in m. Linear, so it also returns its matrices
(:meth:`state_space`), and the simulator takes the exact path.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from torchpaml import Record, PhysicalParameter, Positive, SecondOrderPhysics, register_parameters

__all__ = ["MassSpringDamper", "frequency_response_start"]


class MassSpringDamper(SecondOrderPhysics):
    """$m\\ddot y + c\\dot y + k y = u$: mass ``m`` (kg), damping ``c`` (N s/m), stiffness ``k`` (N/m), all learnable."""

    def __init__(self, m: float = 1.0, c: float = 1.0, k: float = 1.0, *, learn=("m", "c", "k")):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("m", m, "kg", Positive(), "mass"),
            PhysicalParameter("c", c, "N s/m", Positive(), "viscous damping"),
            PhysicalParameter("k", k, "N/m", Positive(), "stiffness"),
        ], learn)

    def acceleration(self, t, x, v, u):
        return (u - self.c * v - self.k * x) / self.m

    def state_space(self):
        zero, one = torch.zeros((), dtype=torch.float64), torch.ones((), dtype=torch.float64)
        A = torch.stack([torch.stack([zero, one]), torch.stack([-self.k / self.m, -self.c / self.m])])
        B = torch.stack([zero, 1 / self.m]).reshape(2, 1)
        return A, B, torch.tensor([[1.0, 0.0]], dtype=torch.float64), torch.zeros(1, 1, dtype=torch.float64)


def frequency_response_start(record: Record) -> MassSpringDamper:
    r"""A :class:`MassSpringDamper` started from the record's empirical transfer function $|H| = |Y/U|$ over the
    excited bins: $k = 1/|H(0)|$ (the lowest excited decade's median gain), $\omega_0$ at the peak of $|H|$,
    $m = k/\omega_0^2$, and $c = 1/(\omega_0 |H(\omega_0)|)$ from the resonance's height.
    """
    U, Y = np.fft.rfft(record.u[:, 0].numpy()), np.fft.rfft(record.y[:, 0].numpy())
    f = np.fft.rfftfreq(len(record.t), float(record.dt))
    excited = (f > 0) & (np.abs(U) > 0.1 * np.abs(U[1:]).max())
    gain = np.where(excited, np.abs(Y) / np.where(excited, np.abs(U), 1.0), 0.0)
    peak = int(np.argmax(gain))
    static = float(np.median(gain[excited & (f < 10 * f[excited].min())]))
    omega0 = 2 * math.pi * f[peak]
    k = 1 / static
    return MassSpringDamper(m=k / omega0**2, c=1 / (omega0 * gain[peak]), k=k)
