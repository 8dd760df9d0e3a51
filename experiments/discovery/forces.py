"""Forces that the library does not have, written as a user would: the truths of the discovery cases.

Between them they act through damping, stiffness and the input:

* :class:`CubicDamping`, $F = -c\\,v^3$;
* :class:`AmplitudeDamping`, damping that grows with amplitude (van der Pol's), $F = -c\\,x^2 v$;
* :class:`ElectrostaticSoftening`, a MEMS resonator's spring softened by its drive, $F = +c\\,u^2 x$;
* :class:`ForceFactor`, a loudspeaker's force factor falling with excursion, $F = -c\\,x^2 u$.
"""

from __future__ import annotations

from torchpaml import AbstractEffect, PhysicalParameter, Real, register_parameters


class _Force(AbstractEffect):
    """c times a shape of (x, v, u); c is the strength."""

    def __init__(self, c: float = 0.0, *, learn=("c",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("c", c, "-", Real(), f"{self.name} coefficient")], learn)


class CubicDamping(_Force):
    name, equation = "cubic_damping", "- c*v^3"

    def force(self, physics, x, v, u):
        return -self.c * v**3


class AmplitudeDamping(_Force):
    name, equation = "amplitude_damping", "- c*x^2*v"

    def force(self, physics, x, v, u):
        return -self.c * x**2 * v


class ElectrostaticSoftening(_Force):
    name, equation = "electrostatic_softening", "+ c*u^2*x"

    def force(self, physics, x, v, u):
        return self.c * u**2 * x


class ForceFactor(_Force):
    name, equation = "force_factor", "- c*x^2*u"

    def force(self, physics, x, v, u):
        return -self.c * x**2 * u


#: case -> (effect at its true strength, the term discovery should write, its coefficient in the force)
OUTSIDE = {
    "cubic_damping": (lambda: CubicDamping(0.5), "v**3", -0.5),
    "amplitude_damping": (lambda: AmplitudeDamping(1.0), "v*x**2", -1.0),
    "electrostatic_softening": (lambda: ElectrostaticSoftening(0.8), "u**2*x", 0.8),
    "force_factor": (lambda: ForceFactor(0.5), "u*x**2", -0.5),
}
