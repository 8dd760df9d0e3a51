r"""A user's physics for the cascaded tanks, and the effects it may miss, written as a user would.

The physics (linear outflows, every parameter learnable):

$$ \dot x_1 = -k_1 x_1 + k_4 u, \qquad \dot x_2 = k_2 x_1 - k_3 x_2, \qquad y = x_2 , $$

with x1 the upper and x2 the lower level (in sensor volts). The effects:

* :class:`TorricelliOutflow` (``sqrt_outflow_upper``, ``sqrt_outflow_lower``): a tank's outflow
  through its opening grows as $\sqrt{\text{level}}$ (Bernoulli), not as the level; a *rate* on the
  tank's equation and, for the upper tank, on the lower one, which that flow feeds;
* :class:`UpperOverflow` (``upper_overflow``): above a level the upper tank spills; a share of the
  spill falls into the lower tank, the rest returns to the reservoir: *rates* on both equations;
* :class:`SensorClip` (``sensor_clip``): the lower tank overflows and the measured level clips, at
  :data:`CLIP_LEVEL` = 10 V by the README's count of the clipped samples (fitted, and probed where it acts): an
  *output map*;
* :class:`LowerOverflow` (``lower_overflow``): the lower tank spills above a level, so its level, not only its
  reading, stops rising there: a *rate* on the lower tank's equation;
* :class:`SensorOffset` (``sensor_offset``): the uncalibrated sensor's zero lies off the lower tank's outlet, so the
  outflow's law acts on the level plus an offset: an *output map*, tried on the final model beside the diagnosis.
"""

from __future__ import annotations

import torch

from torchpaml import (
    AbstractEffect,
    AbstractPhysics,
    Interval,
    PhysicalParameter,
    Positive,
    Real,
    register_parameters,
    state_vector,
)

__all__ = ["CLIP_LEVEL", "FREE_SPILL_RATE", "LowerOverflow", "MAX_SPILL_RATE", "SensorClip", "SensorOffset",
           "TorricelliOutflow", "TwoTanks", "UpperOverflow"]

CLIP_LEVEL = 10.0
#: 1/s: the fastest spill the 4 s samples resolve explicitly, one sample interval (the default bound).
MAX_SPILL_RATE = 0.25
#: 1/s: the bound of a free spill rate (``--free-spill``), far beyond anything the 4 s samples tell from an
#: instant spill.
FREE_SPILL_RATE = 1000.0


def levels_in_range(records) -> list[dict[str, float]]:
    """The starts of an effect that acts above a ``level``: its own, then the measured output's 90th and 75th
    percentiles, where it acts on the fitted output."""
    y = torch.cat([r.y.flatten() for r in records])
    return [{}, *({"level": float(torch.quantile(y, q))} for q in (0.9, 0.75))]


class TwoTanks(AbstractPhysics):
    """Two cascaded tanks with linear outflows (module docstring). State (batch, 2) = (upper, lower).

    ``levels``: the initial state of :meth:`initial_state`, the start of a fit that estimates it.
    """

    state_names = ("upper", "lower")

    def __init__(self, k1=0.01, k2=0.01, k3=0.01, k4=0.01, *, levels=(0.0, 0.0), learn=("k1", "k2", "k3", "k4")):
        super().__init__()
        self.levels = tuple(float(level) for level in levels)
        register_parameters(self, [
            PhysicalParameter("k1", k1, "1/s", Positive(), "upper outflow rate"),
            PhysicalParameter("k2", k2, "1/s", Positive(), "inflow rate of the lower tank"),
            PhysicalParameter("k3", k3, "1/s", Positive(), "lower outflow rate"),
            PhysicalParameter("k4", k4, "1/s", Positive(), "pump gain"),
        ], learn)

    def initial_state(self, batch: int) -> torch.Tensor:
        """``levels`` (rest by default), (batch, 2): where a fit that estimates the initial state starts."""
        return torch.tensor([self.levels], dtype=torch.float64).expand(batch, 2).clone()

    def derivative(self, t, x, u):
        upper, lower = x[..., 0], x[..., 1]
        return state_vector([-self.k1 * upper + self.k4 * u[..., 0], self.k2 * upper - self.k3 * lower])

    def output(self, x, u):
        return x[..., 1:]

    def state_space(self):
        zero = torch.zeros((), dtype=torch.float64)
        A = torch.stack([torch.stack([-self.k1, zero]), torch.stack([self.k2, -self.k3])])
        B = torch.stack([self.k4, zero]).reshape(2, 1)
        C = torch.tensor([[0.0, 1.0]], dtype=torch.float64)
        return A, B, C, torch.zeros(1, 1, dtype=torch.float64)


class TorricelliOutflow(AbstractEffect):
    r"""A tank's outflow bends from linear towards Torricelli: $k\,x \to k\,x^{1 - g/2}$.

    $g = 0$ is the base's linear outflow and $g = 1$ the square-root law of Bernoulli/Torricelli for a
    level read in length units, so the base's rate $k$ keeps its meaning and the effect is a *rate*
    $-k\,(x^{1-g/2} - x)$ on the tank's equation. The sensor here is uncalibrated (its zero and its
    scale in volts are unknown), so on its scale physics fixes the exponent only as far as the outflow
    growing with the level, no faster than linearly: $g \in [0, 2]$ is the physical range. For
    ``tank="upper"`` the same flow enters the lower tank with the base's inflow rate $k_2$: at
    $g = 1$ the model is the benchmark document's $\dot x_1 = -k_1\sqrt{x_1} + k_4 u$,
    $\dot x_2 = k_2\sqrt{x_1} - k_3 x_2$. Levels below $10^{-9}$ count as $10^{-9}$.
    """

    states = ("upper", "lower")

    def __init__(self, g: float = 0.0, tank: str = "upper", *, learn=("g",)):
        super().__init__()
        if tank not in ("upper", "lower"):
            raise ValueError(f"tank must be 'upper' or 'lower', got {tank!r}")
        self.tank, self.name = tank, f"sqrt_outflow_{tank}"
        self.equation = f"k*x_{tank} -> k*x_{tank}^(1 - g/2)"
        register_parameters(self, [PhysicalParameter("g", g, "-", Interval(-1.0, 2.0),
                                                     "outflow law: 0 linear, 1 square root", physical=(0.0, 2.0))],
                            learn)

    def rate(self, physics, x, u):
        level = x[..., self.states.index(self.tank)].clamp(min=1e-9)
        bend = level ** (1 - self.g / 2) - level
        if self.tank == "lower":
            return self.on_state(physics, x, {"lower": -physics.k3 * bend})
        return self.on_state(physics, x, {"upper": -physics.k1 * bend, "lower": physics.k2 * bend})


class UpperOverflow(AbstractEffect):
    r"""The upper tank spills above its rim: $q = c\,\max(x_1 - h\,k_4/k_1, 0)$ leaves it, $s\,q\,k_2/k_1$ reaches the lower one.

    The rim $h$ is given in input volts: the level that a constant input of $h$ V settles at
    ($k_4 h / k_1$), so that it does not depend on the unmeasured scale of the upper level. ``h`` is a
    shape parameter (fixed at its start, freed by the ranking when the data asks); $s \in [0, 1]$ is
    the share of the spill that falls into the lower tank.

    The rate $c$ is bounded by ``max_rate``, by default :data:`MAX_SPILL_RATE`: one sample interval,
    where RK4 resolves the spill. ``max_rate=FREE_SPILL_RATE`` leaves it free: a fast spill is stiff on
    the 4 s grid, and the fit integrates it with the implicit TR-BDF2, which its step check chooses
    where RK4's step would be unstable.
    """

    name, equation = "upper_overflow", "- c*max(x_upper - h*k4/k1, 0), s of it into the lower tank"
    states = ("upper", "lower")
    shape = ("h",)

    def __init__(self, c: float = 0.0, h: float = 5.0, s: float = 0.5, *, max_rate: float = MAX_SPILL_RATE,
                 learn=("c", "s")):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("c", c, "1/s", Interval(-max_rate, max_rate), "spill rate above the rim",
                              physical=(0.0, max_rate)),
            PhysicalParameter("h", h, "V (input)", Positive(), "rim, as the input that settles there"),
            PhysicalParameter("s", s, "-", Interval(0.0, 1.0), "share of the spill into the lower tank"),
        ], learn)

    def rate(self, physics, x, u):
        rim = self.h * physics.k4 / physics.k1
        spill = self.c * (x[..., 0] - rim).clamp(min=0)
        return self.on_state(physics, x, {"upper": -spill, "lower": self.s * physics.k2 / physics.k1 * spill})


class SensorClip(AbstractEffect):
    r"""The measured level clips at a level $L$: $y \to y - w\,\max(y - L, 0)$; $w = 1$ is a hard clip.

    $L$ starts at :data:`CLIP_LEVEL` (10 V, where the README counts the clipped samples) and is fitted with $w$.
    The ranking probes it from levels inside the measured output's range too (:meth:`starts`: its 90th and 75th
    percentiles), where the clip acts on the fitted output: at 10 V it acts only where the fitted level reaches 10 V,
    which its fit may miss by a rounding, and a probe that moves no sample cannot judge it.
    """

    name, equation = "sensor_clip", "y -> y - w*max(y - L, 0)"

    def __init__(self, w: float = 0.0, level: float = CLIP_LEVEL, *, learn=("w", "level")):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("w", w, "-", Interval(-0.5, 1.5), "share of the excess clipped", physical=(0.0, 1.0)),
            PhysicalParameter("level", level, "V", Positive(), "clip level"),
        ], learn)

    def starts(self, records):
        return levels_in_range(records)

    def output_map(self, y):
        return y - self.w * (y - self.level).clamp(min=0)


class LowerOverflow(AbstractEffect):
    r"""The lower tank spills above a level $L$: $q = c\,\max(x_2 - L, 0)$ leaves it, back to the reservoir.

    :class:`SensorClip` clips the reading at the rim, but the level it reads would go on rising and drain later
    through the outlet; a spill stops the level itself. $L$ starts at :data:`CLIP_LEVEL` and is fitted with $c$,
    bounded by ``max_rate`` (:data:`MAX_SPILL_RATE`, one sample interval, as :class:`UpperOverflow`'s). As
    :class:`SensorClip`, it is probed from levels inside the measured range too (:meth:`starts`), where it acts.
    """

    name, equation = "lower_overflow", "- c*max(x_lower - L, 0)"
    states = ("upper", "lower")

    def __init__(self, c: float = 0.0, level: float = CLIP_LEVEL, *, max_rate: float = MAX_SPILL_RATE,
                 learn=("c", "level")):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("c", c, "1/s", Interval(-max_rate, max_rate), "spill rate above the level",
                              physical=(0.0, max_rate)),
            PhysicalParameter("level", level, "V", Positive(), "level where the lower tank spills"),
        ], learn)

    def starts(self, records):
        return levels_in_range(records)

    def rate(self, physics, x, u):
        return self.on_state(physics, x, {"lower": -self.c * (x[..., 1] - self.level).clamp(min=0)})


class SensorOffset(AbstractEffect):
    r"""The sensor reads the lower level $b$ below the level the outflow's law sees: $y \to y - b$.

    The benchmark's document calls the level sensors uncalibrated: their zero need not sit at the tank's outlet. The
    model's lower level is then the outlet's head, the one Torricelli's law bends, and the reading is that head less
    $b$ (in V, of either sign)."""

    name, equation = "sensor_offset", "y -> y - b"

    def __init__(self, b: float = 0.0, *, learn=("b",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("b", b, "V", Real(), "the sensor's zero below the outlet")], learn)

    def output_map(self, y):
        return y - self.b
