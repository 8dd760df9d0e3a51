r"""A user's physics of the EMPS positioning system: a rigid body driven by the motor's force.

$$ M\,\ddot q = g_\tau\,v_{ir} - F_v\,\dot q, \qquad y = q, $$

$g_\tau$ the drive gain of the benchmark (N/V, fixed), $M$ the moving mass and $F_v$ the viscous friction (both
fitted). Linear: it gives its matrices, so it is simulated exactly. What it misses (Coulomb friction, an offset)
the ranking adds from the library, whose effects are accelerations (a force over $M$).
"""

from __future__ import annotations

import torch

from torchpaml import PhysicalParameter, Positive, SecondOrderPhysics, register_parameters

#: The drive gain of the benchmark, N/V (``shared/data/emps/README.md``).
GTAU = 35.15065188


class RigidBody(SecondOrderPhysics):
    """$M\\ddot q = g_\\tau u - F_v\\dot q$ (module docstring); state (position m, velocity m/s), input V."""

    def __init__(self, M: float = 95.0, Fv: float = 200.0, *, learn=("M", "Fv")):
        super().__init__()
        register_parameters(self, [PhysicalParameter("M", M, "kg", Positive(), "moving mass"),
                                   PhysicalParameter("Fv", Fv, "N s/m", Positive(), "viscous friction")], learn)

    def acceleration(self, t, x, v, u):
        return (GTAU * u - self.Fv * v) / self.M

    def state_space(self):
        zero = torch.zeros((), dtype=torch.float64)
        A = torch.stack([torch.stack([zero, zero + 1]), torch.stack([zero, -self.Fv / self.M])])
        B = torch.stack([zero[None], (GTAU / self.M)[None]])
        return A, B, torch.tensor([[1.0, 0.0]], dtype=torch.float64), torch.zeros(1, 1, dtype=torch.float64)
