r"""A user's physics with two degrees of freedom, for the tests of devices with several sensors.

Two masses on a line, a force on the first, both positions measured:

$$ \dot v_1 = b\,u - k_g x_1 - k (x_1 - x_2) - c (v_1 - v_2) - d_1 v_1, \qquad
   \dot v_2 = k (x_1 - x_2) + c (v_1 - v_2) - d_2 v_2, \qquad y = (x_1, x_2), $$

per unit mass (every term an acceleration). Linear: it gives its matrices, so it is simulated exactly. The device
the tests measure has Coulomb friction on the second mass only: ``TwoMass() + CoulombFriction(...).on("v2")``.
"""

import torch

from torchpaml import AbstractPhysics, PhysicalParameter, Positive, register_parameters, state_vector

#: The device's values: the physics' and its Coulomb friction on mass 2 (an acceleration, m/s^2).
TRUTH = {"b": 2.0, "kg": 4.0, "k": 6.0, "c": 0.4, "d1": 0.3, "d2": 0.2}
FRICTION = 0.4


class TwoMass(AbstractPhysics):
    """The two-mass chain of the module docstring; state (x1, x2, v1, v2), input (force,), output (x1, x2)."""

    state_names = ("x1", "x2", "v1", "v2")
    degrees_of_freedom = (("x1", "v1"), ("x2", "v2"))
    output_dim = 2

    def __init__(self, b=1.0, kg=3.0, k=5.0, c=0.5, d1=0.5, d2=0.5, *, learn=("b", "kg", "k", "c", "d1", "d2")):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("b", b, "m/(s^2 N)", Positive(), "input gain"),
            PhysicalParameter("kg", kg, "1/s^2", Positive(), "spring of mass 1 to the ground"),
            PhysicalParameter("k", k, "1/s^2", Positive(), "coupling spring"),
            PhysicalParameter("c", c, "1/s", Positive(), "coupling damping"),
            PhysicalParameter("d1", d1, "1/s", Positive(), "damping of mass 1"),
            PhysicalParameter("d2", d2, "1/s", Positive(), "damping of mass 2"),
        ], learn)

    def derivative(self, t, x, u):
        x1, x2, v1, v2 = x.unbind(-1)
        spring, damper = self.k * (x1 - x2), self.c * (v1 - v2)
        return state_vector([v1, v2, self.b * u[..., 0] - self.kg * x1 - spring - damper - self.d1 * v1,
                             spring + damper - self.d2 * v2])

    def output(self, x, u):
        return x[..., :2]

    def state_space(self):
        zero, one = torch.zeros((), dtype=torch.float64), torch.ones((), dtype=torch.float64)
        A = torch.stack([torch.stack([zero, zero, one, zero]), torch.stack([zero, zero, zero, one]),
                         torch.stack([-self.kg - self.k, self.k, -self.c - self.d1, self.c]),
                         torch.stack([self.k, -self.k, self.c, -self.c - self.d2])])
        B = torch.stack([zero, zero, self.b, zero]).reshape(4, 1)
        C = torch.tensor([[1.0, 0, 0, 0], [0, 1.0, 0, 0]], dtype=torch.float64)
        return A, B, C, torch.zeros(2, 1, dtype=torch.float64)
