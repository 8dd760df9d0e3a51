r"""Input signals as float64 tensors of shape (batch, time, 1), time in seconds, seeded.

Every generator takes a time grid ``t`` (time,) (see :func:`time_grid`) and returns samples. The
simulators hold inputs linearly between samples, so a generator's samples define the input fully
when it is piecewise linear on the grid (the pseudorandom input) and to $O(\Delta t^2)$ otherwise.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from torchpaml._errors import ConfigurationError
from scipy import signal as sps

__all__ = ["amplitude_spectrum", "chirp", "cosine", "dominant_frequency", "multisine", "pseudorandom",
           "pseudorandom_knots", "sine", "time_grid"]


def time_grid(duration: float, dt: float) -> torch.Tensor:
    """$t_k = k\\,\\Delta t$ for $k = 0, \\dots, N-1$ with $N = \\mathrm{round}(T/\\Delta t)$; shape (N,)."""
    n = int(round(duration / dt))
    if n < 2:
        raise ConfigurationError(f"duration {duration} s at dt {dt} s gives {n} samples; need at least 2")
    return torch.arange(n, dtype=torch.float64) * dt


def sine(t: torch.Tensor, amplitude: float, omega: float, phase: float = 0.0) -> torch.Tensor:
    r"""$u = \alpha\sin(\omega t + \phi)$, shape (1, time, 1)."""
    return (amplitude * torch.sin(omega * t + phase))[None, :, None]


def cosine(t: torch.Tensor, amplitude: float, omega: float, phase: float = 0.0) -> torch.Tensor:
    r"""$u = \alpha\cos(\omega t + \phi)$ (the paper's witness input), shape (1, time, 1)."""
    return (amplitude * torch.cos(omega * t + phase))[None, :, None]


def pseudorandom_knots(t: torch.Tensor, period: float = 0.8) -> torch.Tensor:
    """Knot times $0, P, 2P, \\dots$ covering ``t``, shape (K,)."""
    count = int(math.floor(float(t[-1]) / period)) + 2
    return torch.arange(count, dtype=torch.float64) * period


def pseudorandom(
    t: torch.Tensor, amplitude: float, period: float = 0.8, *, batch: int = 1, seed: int = 0
) -> torch.Tensor:
    r"""The paper's input: i.i.d. $\mathrm{Uniform}(-\alpha, \alpha)$ knots every ``period`` s, linearly interpolated.

    Returns shape (batch, time, 1); $|u| \le \alpha$. Reproducible for a given ``seed``.
    """
    generator = torch.Generator().manual_seed(seed)
    knots = pseudorandom_knots(t, period)
    values = (2 * torch.rand(batch, len(knots), generator=generator, dtype=torch.float64) - 1) * amplitude
    k = torch.clamp((t / period).floor().long(), max=len(knots) - 2)
    w = (t - knots[k]) / period
    return (values[:, k] * (1 - w) + values[:, k + 1] * w)[..., None]


def multisine(
    t: torch.Tensor,
    amplitude: float,
    frequencies: torch.Tensor | list[float],
    *,
    batch: int = 1,
    seed: int = 0,
) -> torch.Tensor:
    r"""Random-phase multisine $\sum_k \cos(2\pi f_k t + \varphi_k)$, $\varphi_k \sim U[0, 2\pi)$, scaled to peak $\alpha$.

    ``frequencies`` in Hz. Returns shape (batch, time, 1) with $\max_t |u| = \alpha$ per batch row.
    """
    f = torch.as_tensor(frequencies, dtype=torch.float64)
    generator = torch.Generator().manual_seed(seed)
    phases = 2 * math.pi * torch.rand(batch, len(f), generator=generator, dtype=torch.float64)
    u = torch.cos(2 * math.pi * f[None, None, :] * t[None, :, None] + phases[:, None, :]).sum(-1)
    return (amplitude * u / u.abs().amax(dim=1, keepdim=True))[..., None]


def chirp(t: torch.Tensor, amplitude: float, f0: float, f1: float, method: str = "linear") -> torch.Tensor:
    r"""Swept sine $\alpha\cos(\phi(t))$ from ``f0`` Hz at $t_0$ to ``f1`` Hz at $t_{N-1}$ (``scipy.signal.chirp``)."""
    u = sps.chirp(t.numpy(), f0=f0, t1=float(t[-1]), f1=f1, method=method)
    return (amplitude * torch.from_numpy(u))[None, :, None]


def _flat(x) -> np.ndarray:
    """A tensor or array of one channel, (time,) or (1, time, 1), as a float array (time,)."""
    x = x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)
    return x.astype(float).reshape(-1)


def amplitude_spectrum(t, signal) -> tuple[np.ndarray, np.ndarray]:
    r"""The one-sided amplitude spectrum of ``signal`` (time,) on the uniform grid ``t`` (time,): the frequencies
    $\omega_k$ in rad/s and $2|X_k|/N$ (a sine of amplitude $a$ on a bin shows $a$)."""
    t, x = _flat(t), _flat(signal)
    return 2 * math.pi * np.fft.rfftfreq(len(x), d=float(t[1] - t[0])), 2 * np.abs(np.fft.rfft(x)) / len(x)


def dominant_frequency(t, u) -> float:
    """The frequency (rad/s) of the largest non-DC line of ``u``'s amplitude spectrum (``u`` (time,) or (1, time, 1))."""
    u = _flat(u)
    frequencies, amplitude = amplitude_spectrum(t, u - u.mean())
    return float(frequencies[1 + int(np.argmax(amplitude[1:]))])
