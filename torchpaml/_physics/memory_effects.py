r"""Effects with memory: each carries a state of its own, integrated with the physics (``own_states``).

==================== ================================================================ ===========================
name                 term                                                             parameters (start)
==================== ================================================================ ===========================
hysteresis           $F = -k z$, $\dot z = v - \gamma |v| z - \delta\, v |z|$ (Bouc-Wen, n = 1)   k (0), gamma (1/rms y), delta (0)
dynamic_friction     $F = -\sigma_0 (z + \tau_1 \dot z)$, $\dot z = v - |v| z / (z_c\, g(v))$ (LuGre)   sigma0 (0), zc (rms y / 10), ...
input_lag            $\tilde u = u_\ell$, $\dot u_\ell = (u - u_\ell)/\tau$ (a first-order lag; $\tilde u = u$ at $\tau = 0$)   tau (0)
latent_state         $\tilde u = u + g z$, $\dot z = \lambda (u - z)$ (a slow memory of the input beside its direct path)   g (0), lam
==================== ================================================================ ===========================

The forces act on second-order (mechanical) physics, the lag and the latent state on the input of any single-input
physics. Each is off at zero strength (k, sigma0, tau, g = 0), where its state may evolve but does not act, so the
ranking scores it like any effect (:func:`~torchpaml.rank_missing_effects`). Where a
default depends on the record's scale (a hysteretic displacement, a bristle deflection), the effect gives the
ranking starts scaled to the measured output (:meth:`~torchpaml.AbstractEffect.starts`).
"""

from __future__ import annotations

import math

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._parameters import PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics.effect import AbstractEffect, EffectState

__all__ = ["DynamicFriction", "Hysteresis", "InputLag", "LatentState"]


def _output_scale(records: list) -> float:
    """The RMS of the measured outputs over ``records``; 1 for an output that is zero throughout."""
    y = torch.cat([record.y.flatten() for record in records])
    scale = float(torch.sqrt(torch.mean(y**2)))
    return scale if scale > 0 else 1.0


def sample_interval(records: list) -> float | None:
    """The shortest median sampling interval over ``records`` (where a lag is probed), ``None`` without one."""
    steps = [float(torch.median(torch.diff(r.t))) for r in records if len(r.t) > 1]
    return min(steps) if steps else None


def _largest_step(records: list) -> float:
    """The largest change of the measured output over one sample, over ``records`` (0 for records of one sample)."""
    return max((float(torch.diff(r.y, dim=0).abs().max()) for r in records if len(r.t) > 1), default=0.0)


class Hysteresis(AbstractEffect):
    r"""Bouc-Wen hysteresis on a second-order physics:

    $$ F = -k\,z, \qquad \dot z = v - \gamma\,|v|\,z - \delta\,v\,|z| . $$

    This is Bouc-Wen's $\dot z = A v - \beta(\gamma |v| |z|^{n-1} z + \delta v |z|^n)$ with $A = 1$ (its scale is
    $k$'s) and $\beta$ folded into $\gamma$ and $\delta$, which here carry the unit 1/[x]. The exponent is fixed at
    $n = 1$: Bouc's original model and the Bouc-Wen benchmark's, the only one whose hysteretic restoring force is
    piecewise linear in $z$ between velocity reversals; an $n < 1$ makes $|z|^{n-1}$ infinite at $z = 0$, and $n$
    is nearly unidentifiable beside $\gamma$ and $\delta$ in a record that does not reach saturation. To fit another
    $n$, subclass and override :meth:`state_rate`.

    Physical ranges: $k \ge 0$ (a restoring force); $\gamma + \delta > 0$ softens the loop towards the
    saturation $|z| = 1/(\gamma + \delta)$, $\gamma + \delta < 0$ hardens it. State: ``z`` in [x] (position units),
    starting at 0. Where $\gamma$ was not given, the ranking starts from three loop shapes that bend at the
    record's amplitude, $\gamma = 1/\mathrm{rms}(y)$ and $\delta \in \{0, -\gamma, \gamma\}$ (linear loading and
    stiffer unloading, hardening, softening), and scores and refits the most promising: from a wrong shape the fit
    can end in a loop of the opposite sense.
    """

    name = "hysteresis"
    equation = "- k*z, z' = v - gamma*|v|*z - delta*v*|z|"
    own_states = (EffectState("z", "[x]", 0.0, "hysteretic displacement"),)

    def __init__(self, k: float = 0.0, gamma: float | None = None, delta: float = 0.0, *,
                 learn=("k", "gamma", "delta")):
        super().__init__()
        self._shaped = gamma is not None
        register_parameters(self, [
            PhysicalParameter("k", k, "1/s^2", Real(), "hysteretic stiffness", physical=(0.0, math.inf)),
            PhysicalParameter("gamma", 1.0 if gamma is None else gamma, "1/[x]", Real(), "loop shape, |v| z term"),
            PhysicalParameter("delta", delta, "1/[x]", Real(), "loop shape, v |z| term"),
        ], learn)

    def starts(self, records):
        if self._shaped:
            return [{}]
        gamma = 1.0 / _output_scale(records)
        return [{"gamma": gamma, "delta": delta} for delta in (0.0, -gamma, gamma)]

    def bounds(self, records):
        r"""$|\gamma|, |\delta| \le 2/\min(\Delta, \mathrm{rms}(y))$, $\Delta$ the largest change of y over one sample:
        the loop's own rate, $(|\gamma| + |\delta|)\,|v|$ with $|v|\,h \lesssim \Delta$, then stays within four times the
        sampling rate, which RK4 integrates in a few substeps. Beyond, the loop closes faster than the samples
        resolve (a stiff state: measured on an oscillator with cubic stiffness, 4 001 samples, a refit drove
        $\gamma$ from 5 to 313 and each evaluation from 0.04 to 3.5 s). The Bouc-Wen benchmark's loop
        ($\gamma = 796$, $\delta = -1095$ per m, against a limit of 2 538) lies well inside; so do the starts."""
        if self._shaped:
            return {}
        step = min(_largest_step(records), _output_scale(records))
        limit = 2.0 / step if step > 0 else math.inf
        return {} if limit == math.inf else {"gamma": (-limit, limit), "delta": (-limit, limit)}

    def force(self, physics: AbstractPhysics, x, v, u, z):
        return -self.k * z[..., 0]

    def state_rate(self, physics: AbstractPhysics, x, z, u):
        v, zeta = x[..., 1], z[..., 0]
        return (v - self.gamma * v.abs() * zeta - self.delta * v * zeta.abs())[..., None]


class DynamicFriction(AbstractEffect):
    r"""LuGre friction on a second-order physics: bristles of deflection $z$,

    $$ F = -\sigma_0\,(z + \tau_1 \dot z), \qquad \dot z = v - \frac{|v|\,z}{z_c\, g(v)}, \qquad
       g(v) = 1 + (r - 1)\,e^{-(v/v_s)^2} . $$

    In steady sliding $z = z_c\,g(v)\,\mathrm{sign}(v)$, so the friction is $\sigma_0 z_c$ (Coulomb) at speed and
    $r$ times that (static) near rest; below $z_c$ the contact is a spring of stiffness $\sigma_0$ (pre-sliding).
    The Coulomb level is ``sigma0 * zc``. LuGre's viscous term $\sigma_2 v$ is the physics' own damping, left out.
    With $r = 1$ and $\tau_1 = 0$ this is Dahl's model.

    Parameters: ``sigma0`` (strength, bristle stiffness, 1/s^2, >= 0), ``zc`` (Coulomb deflection, [x], > 0),
    ``ratio`` ($r = F_s/F_c \ge 1$, fixed at 1), ``vs`` (Stribeck velocity, [x]/s, fixed), ``tau1`` (bristle damping
    time, s, >= 0; freed by the ranking when the data ask for it). State ``z`` in [x], starting at 0.
    Where ``zc`` and ``vs`` were not given, the ranking starts from a tenth of the output's RMS (at least the
    largest change of y over one sample, below which the bristle state is too fast for the sample interval) and
    a tenth of its rate's RMS.
    """

    name = "dynamic_friction"
    equation = "- sigma0*(z + tau1*z'), z' = v - |v|*z/(zc*g(v))"
    own_states = (EffectState("z", "[x]", 0.0, "bristle deflection"),)
    shape = ("tau1",)

    def __init__(self, sigma0: float = 0.0, zc: float | None = None, ratio: float = 1.0, vs: float | None = None,
                 tau1: float = 0.0, *, learn=("sigma0", "zc")):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("sigma0", sigma0, "1/s^2", Real(), "bristle stiffness", physical=(0.0, math.inf)),
            PhysicalParameter("zc", 1.0 if zc is None else zc, "[x]", Positive(), "Coulomb bristle deflection"),
            PhysicalParameter("ratio", ratio, "-", Real(), "static over Coulomb friction", physical=(1.0, math.inf)),
            PhysicalParameter("vs", 1.0 if vs is None else vs, "[x]/s", Positive(), "Stribeck velocity"),
            PhysicalParameter("tau1", tau1, "s", Real(), "bristle damping time", physical=(0.0, math.inf)),
        ], learn)
        self._given = {"zc": zc is not None, "vs": vs is not None}

    def starts(self, records):
        scale = _output_scale(records)
        changes = [(torch.diff(r.y, dim=0), torch.diff(r.t)[:, None]) for r in records if len(r.t) > 1]
        rates = torch.cat([(dy / dt).flatten() for dy, dt in changes] or [torch.zeros(1, dtype=torch.float64)])
        rate = float(torch.sqrt(torch.mean(rates**2)))
        values = {"zc": max(scale / 10, _largest_step(records)), "vs": (rate if rate > 0 else scale) / 10}
        return [{name: value for name, value in values.items() if not self._given[name]}]

    def bounds(self, records):
        r"""``zc`` at least half the largest change of y over one sample, $\Delta$: below it the bristles' rate
        $|v|/z_c$ exceeds $2/h$ (as $|v|\,h \lesssim \Delta$), near RK4's stability limit at one substep (2.8), a
        stiff state that makes each simulation dearer as it shrinks (measured on a pendulum's refit, 4 001 samples:
        $z_c$ driven to 4.5e-3 and every evaluation 60 times its first), and LuGre's pre-sliding is beyond what the
        records resolve: at the bound the refit reads as Coulomb friction, which the library has. The start,
        $\max(\mathrm{rms}(y)/10, \Delta)$, lies inside."""
        step = _largest_step(records)
        return {} if self._given["zc"] or step == 0.0 else {"zc": (step / 2, math.inf)}

    def _rate(self, v: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        g = 1 + (self.ratio - 1) * torch.exp(-((v / self.vs) ** 2))
        return v - v.abs() * z / (self.zc * g)

    def force(self, physics: AbstractPhysics, x, v, u, z):
        deflection = z[..., 0]
        return -self.sigma0 * (deflection + self.tau1 * self._rate(v, deflection))

    def state_rate(self, physics: AbstractPhysics, x, z, u):
        return self._rate(x[..., 1], z[..., 0])[..., None]


class InputLag(AbstractEffect):
    r"""An actuator or amplifier that lags the command: the physics is driven by $u_\ell$,

    $$ \dot u_\ell = (u - u_\ell)/\tau, \qquad \tilde u = u_\ell \quad (\tau > 0), \qquad \tilde u = u \quad (\tau = 0). $$

    ``tau`` (s, >= 0) is the strength; its first-order direction, $-\tau\dot u$, is probed at one sample
    interval (:meth:`probe`): a lag far shorter than the step is a stiff state, which RK4 cannot take. For physics with one input. State ``u_lag`` in [u], starting at 0 (rest).
    """

    name = "input_lag"
    equation = "u -> u_lag, u_lag' = (u - u_lag)/tau"
    own_states = (EffectState("u_lag", "[u]", 0.0, "lagged input"),)

    def __init__(self, tau: float = 0.0, *, learn=("tau",)):
        super().__init__()
        register_parameters(self, [PhysicalParameter("tau", tau, "s", Real(), "lag time constant",
                                                     physical=(0.0, math.inf))], learn)

    def applies_to(self, physics: AbstractPhysics):
        if physics.input_dim != 1:
            return f"input_lag lags a single input; {physics.display_name} has {physics.input_dim}"
        return super().applies_to(physics)

    def probe(self, records):
        return sample_interval(records)

    def input_map(self, u, z):
        return torch.where(self.tau > 0, z, u)

    def state_rate(self, physics: AbstractPhysics, x, z, u):
        on = self.tau > 0
        return torch.where(on, (u - z) / torch.where(on, self.tau, 1.0), 0.0)


class LatentState(AbstractEffect):
    r"""A latent state with a small learned rate: a slow memory of the input that acts beside its direct path (an
    amplifier or a winding that heats, a reservoir that fills, a seal that creeps),

    $$ \dot z = \lambda\,(u - z), \qquad \tilde u = u + g\,z . $$

    At $g = 0$ the physics sees $u$ (the state evolves but does not act); at $g \ne 0$ the steady-state gain is
    $1 + g$ while a change faster than $1/\lambda$ passes with gain 1. ``g`` (dimensionless) is the strength;
    ``lam`` (1/s) is learned with it, from the slow starts of :meth:`starts`. It tells a memory from an actuator lag
    (:class:`InputLag`, which removes the direct path). For physics with one input. State ``z`` in [u], starting at
    0 (rest).
    """

    name = "latent_state"
    generic = True  # a place more than physics: the simpler-effect rule (ranking.occam)
    equation = "u -> u + g*z, z' = lam*(u - z)"
    own_states = (EffectState("z", "[u]", 0.0, "the input's slow memory"),)

    def __init__(self, g: float = 0.0, lam: float = 1.0, *, learn=("g", "lam")):
        super().__init__()
        register_parameters(self, [
            PhysicalParameter("g", g, "-", Real(), "the memory's gain"),
            PhysicalParameter("lam", lam, "1/s", Positive(), "the memory's rate"),
        ], learn)

    def applies_to(self, physics: AbstractPhysics):
        if physics.input_dim != 1:
            return f"latent_state remembers a single input; {physics.display_name} has {physics.input_dim}"
        return super().applies_to(physics)

    def starts(self, records):
        """``lam`` at three rates spaced evenly in log between five time constants per record and ten samples per
        time constant: a memory slower than the dynamics the physics already has."""
        step = sample_interval(records)
        if step is None:
            return [{}]
        low, high = 5.0 / max(float(r.t[-1] - r.t[0]) for r in records), 0.1 / step
        if not low < high:
            return [{}]
        return [{"lam": low * (high / low) ** (i / 2)} for i in range(3)]

    def input_map(self, u, z):
        return u + self.g * z

    def state_rate(self, physics: AbstractPhysics, x, z, u):
        return self.lam * (u - z)
