r"""Physical effects that physics may be missing, composable with ``+``.

Each effect is an ``nn.Module`` with named, constrained parameters and a registry ``name``. It
acts on the composed model (:mod:`~torchpaml._physics.composed`)

$$ \dot x = f_{\text{base}}(t, x, \tilde u) + \sum_e R_e(x, u) + e_v \sum_e F_e(x, v, u), \qquad
   \tilde u = \text{the input maps of } u, \qquad y = \text{the output maps of } h_{\text{base}}(x, \tilde u), $$

through a *force* $F_e$ on the velocity equation of a degree of freedom (a second-order physics' one, or the one
``effect.on("v2")`` names), a *rate* $R_e$ on
named state equations, or the input and output maps (any physics). The library's nine static ones (the three with memory are in
:mod:`~torchpaml._physics.memory_effects`):

==================== ========================================== ===========================
name                 term                                       parameters (start)
==================== ========================================== ===========================
cubic_stiffness      $F = -k_3 x^3$                             k3 (0)
quadratic_stiffness  $F = -k_2 x^2$                             k2 (0)
pendulum_restoring   $F = \lambda\,\omega_0^2 (x - \sin x)$: at $\lambda = 1$ the base's $\omega_0^2 x$ becomes $\omega_0^2\sin x$   lam (0)
coulomb_friction     $F = -F_c \tanh(v/\varepsilon)$ (a smoothed sign)            Fc (0), eps (0.01, shape)
quadratic_damping    $F = -c_2\, v|v|$                          c2 (0)
constant_force       $F = f_0$                                  f0 (0)
input_saturation     $\tilde u = \tanh(s u)/s$ ($= u_{\max}\tanh(u/u_{\max})$, $s = 1/u_{\max}$)   s (0)
output_saturation    $y = \tanh(s y)/s$ ($= y_{\max}\tanh(y/y_{\max})$)            s (0)
dead_zone            $\tilde u = u - \mathrm{clip}(u, -d, d)$  d (0)
==================== ========================================== ===========================

Every effect starts at zero strength, where the composed model equals the base model: that is
the point where :func:`rank_missing_effects` measures the output sensitivity to each candidate.
Saturations are parametrised by the inverse level $s$ so that zero strength is $s = 0$ (no
saturation) rather than $u_{\max} = \infty$; the physical level $1/s$ is reported alongside.
A *shape* parameter (``eps``: fixed, listed in :attr:`AbstractEffect.shape`) is freed by the ranking
when that lowers the criterion by more than its threshold.
Physical ranges (a refit outside is flagged by the ranking): ``lam`` in [0, 1], ``Fc`` and ``c2`` >= 0.
The forces apply to :class:`~torchpaml.SecondOrderPhysics`; the saturations and the dead
zone to any physics.

Writing your own: subclass :class:`AbstractEffect`, give it a ``name`` and parameters through
:func:`~torchpaml.register_parameters`, and override any of :meth:`AbstractEffect.force`,
:meth:`AbstractEffect.rate` (with ``states`` naming the equations it needs), :meth:`AbstractEffect.input_map`,
:meth:`AbstractEffect.output_map`. The first declared parameter is the effect's *strength*
(:attr:`AbstractEffect.strength`): at strength 0 the effect must leave the model unchanged, and
parameters may arrive batched with shape (rows,), so combine them with signals elementwise.
"""

from __future__ import annotations

import math

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._parameters import PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics.effect import AbstractEffect, EffectState
from torchpaml._physics.memory_effects import (DynamicFriction, Hysteresis, InputLag, LatentState, _largest_step,
                                              sample_interval)
from torchpaml._physics.signal_effects import (ExtraMode, Feedthrough, MagnitudeSensor, QuadraticInput, QuadraticSensor,
                                               SensorLag)



def _tanh_ratio(s: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
    r"""$\tanh(s z)/s$, continued by its limit $z - s^2 z^3/3$ near $s = 0$ (where the quotient is 0/0)."""
    small = (s * z).abs() < 1e-4
    safe = torch.where(s.abs() < 1e-12, torch.ones_like(s), s)
    return torch.where(small, z - s**2 * z**3 / 3, torch.tanh(safe * z) / safe)


class CubicStiffness(AbstractEffect):
    r"""Hardening (k3 > 0) or softening spring, $F = -k_3 x^3$ (Duffing)."""

    name, equation = "cubic_stiffness", "- k3*x^3"

    def __init__(self, k3: float = 0.0, *, learn=("k3",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("k3", k3, "1/(s^2 m^2)", Real(), "cubic stiffness")], learn)

    def force(self, physics: AbstractPhysics, x, v, u):
        return -self.k3 * x**3


class QuadraticStiffness(AbstractEffect):
    r"""Asymmetric spring, $F = -k_2 x^2$."""

    name, equation = "quadratic_stiffness", "- k2*x^2"

    def __init__(self, k2: float = 0.0, *, learn=("k2",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("k2", k2, "1/(s^2 m)", Real(), "quadratic stiffness")], learn)

    def force(self, physics: AbstractPhysics, x, v, u):
        return -self.k2 * x**2


class PendulumRestoring(AbstractEffect):
    r"""Gravity restoring torque: $\omega_0^2 x \to \omega_0^2[(1 - \lambda) x + \lambda \sin x]$, i.e. $F = \lambda\omega_0^2(x - \sin x)$."""

    name, equation = "pendulum_restoring", "+ lam*omega0^2*(x - sin x)"

    def __init__(self, lam: float = 0.0, *, learn=("lam",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("lam", lam, "-", Real(), "share of sin x in the restoring term",
                                                      physical=(0.0, 1.0))],
                            learn)

    def applies_to(self, physics: AbstractPhysics):
        reason = super().applies_to(physics)
        if reason is None and "omega0" not in physics.physical_parameters():
            return f"pendulum_restoring scales with the base's omega0, and {physics.display_name} has none"
        return reason

    def force(self, physics: AbstractPhysics, x, v, u):
        return self.lam * physics.omega0**2 * (x - torch.sin(x))


#: The smallest smoothing velocity of a Coulomb friction a ranking's refit may reach, as a share of the records'
#: largest rate of the output (:meth:`CoulombFriction.bounds`).
SIGN_RESOLUTION = 1e-3


class CoulombFriction(AbstractEffect):
    r"""Dry friction, $F = -F_c\tanh(v/\varepsilon)$; ``eps`` (fixed) is the velocity of the smoothing."""

    name, equation = "coulomb_friction", "- Fc*tanh(v/eps)"
    shape = ("eps",)

    def __init__(self, Fc: float = 0.0, eps: float = 0.01, *, learn=("Fc",)):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("Fc", Fc, "m/s^2", Real(), "Coulomb friction level", physical=(0.0, math.inf)),
            PhysicalParameter("eps", eps, "m/s", Positive(), "smoothing velocity of the sign"),
        ], learn)

    def bounds(self, records):
        r"""``eps`` at least :data:`SIGN_RESOLUTION` of the records' largest rate of the output, $\max|\Delta y|/h$
        (the velocity's scale where the output is the position): below it, $\tanh(v/\varepsilon)$ differs from
        $\mathrm{sign}(v)$ only at speeds the samples do not resolve, so the output cannot tell the width and a fit runs
        it away without end, while the friction's rate $F_c/\varepsilon$ makes every step stiffer (measured on EMPS's
        third rung: unbounded, a refit drove eps from 2e-3 to 1.1e-26 m/s, and the refitted model's TR-BDF2 Newton
        then failed). EMPS's bound is 1.3e-4 m/s; on ``benchmarks/bench_diagnosis.py``'s oscillator records it is
        3.2e-3, against the default 0.01."""
        step = sample_interval(records)
        rate = _largest_step(records) / step if step else 0.0
        return {"eps": (SIGN_RESOLUTION * rate, math.inf)} if rate > 0 else {}

    def force(self, physics: AbstractPhysics, x, v, u):
        return -self.Fc * torch.tanh(v / self.eps)


class QuadraticDamping(AbstractEffect):
    r"""Aerodynamic drag, $F = -c_2\,v|v|$."""

    name, equation = "quadratic_damping", "- c2*v*|v|"

    def __init__(self, c2: float = 0.0, *, learn=("c2",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("c2", c2, "1/m", Real(), "quadratic damping",
                                                               physical=(0.0, math.inf))], learn)

    def force(self, physics: AbstractPhysics, x, v, u):
        return -self.c2 * v * v.abs()


class ConstantForce(AbstractEffect):
    r"""A bias force (gravity on a tilted axis, an offset in the drive), $F = f_0$."""

    name, equation = "constant_force", "+ f0"

    def __init__(self, f0: float = 0.0, *, learn=("f0",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("f0", f0, "m/s^2", Real(), "constant force")], learn)

    def force(self, physics: AbstractPhysics, x, v, u):
        return self.f0 * torch.ones_like(x)


class InputSaturation(AbstractEffect):
    r"""Actuator saturation, $\tilde u = \tanh(s u)/s = u_{\max}\tanh(u/u_{\max})$ with $s = 1/u_{\max}$."""

    name, equation = "input_saturation", "u -> umax*tanh(u/umax)"
    generic = True  # a place more than physics: the simpler-effect rule (ranking.occam)

    def __init__(self, s: float = 0.0, *, learn=("s",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("s", s, "1/[u]", Real(), "inverse input saturation level")],
                            learn)

    def input_map(self, u):
        return _tanh_ratio(self.s, u)


class OutputSaturation(AbstractEffect):
    r"""Sensor saturation, $y = \tanh(s\,y_{\text{base}})/s = y_{\max}\tanh(y_{\text{base}}/y_{\max})$."""

    name, equation = "output_saturation", "y -> ymax*tanh(y/ymax)"
    generic = True  # a place more than physics: the simpler-effect rule (ranking.occam)

    def __init__(self, s: float = 0.0, *, learn=("s",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("s", s, "1/[y]", Real(), "inverse output saturation level")],
                            learn)

    def output_map(self, y):
        return _tanh_ratio(self.s, y)


class DeadZone(AbstractEffect):
    r"""Input dead zone of half-width d: $\tilde u = u - \mathrm{clip}(u, -d, d)$ (0 inside, shifted outside)."""

    name, equation = "dead_zone", "u -> u - clip(u, -d, d)"

    def __init__(self, d: float = 0.0, *, learn=("d",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("d", d, "[u]", Real(), "dead-zone half-width")], learn)

    def input_map(self, u):
        width = self.d.abs()
        return u - torch.maximum(torch.minimum(u, width), -width)


#: The library, by the names used on the command line and in reports: the one list of its effects, from which
#: the package's exports derive (a new library effect is its class and its entry here).
EFFECTS: dict[str, type[AbstractEffect]] = {
    cls.name: cls
    for cls in (CubicStiffness, QuadraticStiffness, PendulumRestoring, CoulombFriction, QuadraticDamping,
                InputSaturation, OutputSaturation, ConstantForce, DeadZone, Hysteresis, DynamicFriction, InputLag,
                SensorLag, MagnitudeSensor, QuadraticSensor, QuadraticInput, Feedthrough, ExtraMode, LatentState)
}
#: The library effects' class names, as ``torchpaml`` exports them.
EFFECT_CLASSES = sorted(cls.__name__ for cls in EFFECTS.values())

__all__ = ["EFFECTS", "EFFECT_CLASSES", "AbstractEffect", "EffectState", "default_effects", *EFFECT_CLASSES]


def default_effects() -> list[AbstractEffect]:
    """A fresh instance of every library effect, at zero strength."""
    return [cls() for cls in EFFECTS.values()]
