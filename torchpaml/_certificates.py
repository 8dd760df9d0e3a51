r"""Incompatibility certificates (Defs. 1 and 2 of the paper), measured on a witness input.

For $u = \alpha\cos(\omega t)$ and a residual $\mathcal R^\gamma$ with parameters drawn at random, the
normalised inner products over a steady-state window $W$: the transient is discarded, the
sampling puts a whole number of samples in each drive period and $W$ spans whole periods, so
distinct harmonics below the Nyquist rate are exactly orthogonal on $W$ (discrete Fourier
orthogonality) and what is left decays with the transient as $T$ grows:

$$ c_0 = \frac{\langle \mathcal R^\gamma[u], \mathcal H^\theta[u]\rangle_W}{\|\mathcal R^\gamma[u]\|_W\,\|\mathcal H^\theta[u]\|_W},
   \qquad
   c_1 = \frac{\langle \mathcal R^\gamma[u], \partial_\theta\mathcal H^\theta[u]\rangle_W}{\|\mathcal R^\gamma[u]\|_W\,\|\partial_\theta\mathcal H^\theta[u]\|_W}. $$

$|c_0| = 0$ for every $\gamma$ is zeroth-order incompatibility, $|c_1| = 0$ first-order. With several output
channels each product is taken channel by channel (every input channel carries the witness) and the largest
counts; with several parameters, the largest over their sensitivities. The
sensitivity $\partial_\theta \mathcal H$ is a central difference with step $10^{-6}\max(1, |\theta|)$
(truncation error $O(10^{-12})$ relative, far below the values certified), one-sided (error
$O(10^{-6})$) where $\theta$ sits within a step of a bound of its constraint.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import torch
from torch import nn

from torchpaml._physics.base import AbstractPhysics
from torchpaml._errors import ConfigurationError
from torchpaml._residual import ChebyshevHammerstein, MLPResidual
from torchpaml._signals import cosine, time_grid
from torchpaml._simulate.simulator import simulate
from torchpaml._simulate.solvers import Solver

__all__ = ["Certificate", "incompatibility_certificates", "draw_chebyshev", "draw_mlp"]


@dataclass
class Certificate:
    """|c0| and |c1| per random draw of the residual's parameters, and the window they were taken on."""

    zeroth: list[float]
    first: list[float]
    window: tuple[float, float]

    @property
    def worst(self) -> tuple[float, float]:
        return max(self.zeroth), max(self.first)


def draw_chebyshev(alpha: float, generator: torch.Generator, **options) -> ChebyshevHammerstein:
    """A Chebyshev-Hammerstein residual with poles uniform in the default band and N(0, 1) numerators."""
    residual = ChebyshevHammerstein(alpha, **options)
    with torch.no_grad():
        for p in residual.parameters():
            p.copy_(torch.randn(p.shape, generator=generator, dtype=p.dtype))
    return residual


def draw_mlp(alpha: float, generator: torch.Generator, y_scale: float = 1.0, **options) -> MLPResidual:
    """An output-additive MLP residual with every weight and bias N(0, 1/fan_in)."""
    residual = MLPResidual(u_scale=alpha, y_scale=y_scale, **options)
    with torch.no_grad():
        for module in residual.modules():
            if isinstance(module, nn.Linear):
                std = 1 / math.sqrt(module.in_features)
                module.weight.copy_(std * torch.randn(module.weight.shape, generator=generator, dtype=torch.float64))
                module.bias.copy_(std * torch.randn(module.bias.shape, generator=generator, dtype=torch.float64))
    return residual


def _normalised(a: torch.Tensor, b: torch.Tensor) -> float:
    """The largest normalised inner product of ``a`` and ``b`` (batch, time, channels) over the channels, in size."""
    return max(abs(float((a[..., c] * b[..., c]).sum() / (torch.linalg.vector_norm(a[..., c])
                                                          * torch.linalg.vector_norm(b[..., c]))))
               for c in range(a.shape[-1]))


def _sensitivity(physics: AbstractPhysics, parameter: str, theta: float, step: float, t, u, y,
                 solver: Solver | None) -> torch.Tensor:
    r"""$\partial_\theta \mathcal H^\theta[u]$ by central differences; one-sided where θ ± step leaves the constraint."""
    points = []
    for shift in (step, -step):
        try:
            points.append((shift, simulate(physics.assign(**{parameter: theta + shift}), t, u, solver=solver)))
        except ValueError:  # θ sits on a bound of its constraint: use the side that stays inside
            points.append((0.0, y))
    physics.assign(**{parameter: theta})
    (s1, y1), (s2, y2) = points
    return (y1 - y2) / (s1 - s2)


def incompatibility_certificates(
    physics: AbstractPhysics,
    draw: Callable[[torch.Generator], nn.Module],
    *,
    alpha: float,
    parameter: str | Sequence[str],
    omega: float = 1.0,
    duration: float = 80.0,
    transient: float | None = None,
    samples_per_period: int = 628,
    draws: int = 20,
    seed: int = 0,
    solver: Solver | None = None,
) -> Certificate:
    r"""|c0|, |c1| (module docstring) for ``draws`` residuals ``draw(generator)`` on $u = \\alpha\\cos\\omega t$.

    Args:
        physics: the physics $\\mathcal H^\\theta$ at the parameter value of interest.
        draw: returns a residual with random parameters from the given generator.
        parameter: the physical parameter $\\theta$ to differentiate with respect to, or several (the largest
            $|c_1|$ over their sensitivities counts).
        duration: record length T in s; ``transient`` (default T/2) is discarded, and the window is
            the last whole number of drive periods that fits after it.
        samples_per_period: sampling, $\Delta t = 2\pi / (\omega \cdot$ ``samples_per_period``$)$.
        solver: how the physics is simulated (:func:`~torchpaml.simulate`; a fit's ``PhysicsEstimate.solver``),
            default ``Auto()``.
    """
    period = 2 * math.pi / omega
    dt = period / samples_per_period
    t = time_grid(duration, dt)
    u = cosine(t, alpha, omega).expand(-1, -1, physics.input_dim)  # the witness on every input channel
    transient = duration / 2 if transient is None else transient
    periods = math.floor((duration - transient) / period)
    if periods < 1:
        raise ConfigurationError(f"no whole drive period of {period:.3g} s fits after the transient; increase duration")
    window = torch.zeros(len(t), dtype=torch.bool)
    window[len(t) - periods * samples_per_period :] = True
    start, end = float(t[window][0]), float(t[-1]) + dt
    names = [parameter] if isinstance(parameter, str) else list(parameter)
    with torch.no_grad():
        y = simulate(physics, t, u, solver=solver)
        sensitivities = []
        for name in names:
            theta = physics.physical_parameters()[name]
            sensitivities.append(_sensitivity(physics, name, theta, 1e-6 * max(1.0, abs(theta)), t, u, y, solver))
        generator = torch.Generator().manual_seed(seed)
        zeroth, first = [], []
        for _ in range(draws):
            r = draw(generator)(t, u, y)[:, window]
            zeroth.append(_normalised(r, y[:, window]))
            first.append(max(_normalised(r, sensitivity[:, window]) for sensitivity in sensitivities))
    return Certificate(zeroth, first, (start, end))
