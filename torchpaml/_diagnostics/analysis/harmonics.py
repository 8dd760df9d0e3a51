r"""The harmonic fingerprint of a residual under periodic excitation.

For a drive of fundamental $\omega$ (rad/s), the residual $e = y - \hat y$ over a steady-state window is
fitted by least squares with $c_0 + \sum_{k=1}^{K} a_k\cos k\omega t + b_k\sin k\omega t$. Its energy
$\|e\|^2$ then splits into parts:
- **excited**: the lines the input itself contains;
- **odd** and **even**: the non-excited harmonics. Odd ones come from odd nonlinearities (cubic
  stiffness, saturation, a pendulum), even ones from asymmetric ones (quadratic stiffness, a bias
  force);
- **dc**;
- **other**: what no harmonic explains, such as noise, a transient left in the window, or
  sub-harmonics.
A linear model that is wrong only in its parameters leaves its residual on the excited lines. A
missing nonlinearity shows up on the non-excited harmonics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from torchpaml._errors import ConfigurationError

__all__ = ["HarmonicFingerprint", "harmonic_fingerprint"]


def _numpy(x) -> np.ndarray:
    return x.detach().cpu().numpy().reshape(-1) if isinstance(x, torch.Tensor) else np.asarray(x, float).reshape(-1)


@dataclass
class HarmonicFingerprint:
    """Shares of the residual's energy in the window, and the excited harmonic numbers.

    The shares sum to 1 exactly over a whole number of periods; otherwise the harmonics leak into
    each other slightly (about 1e-7 for 20 periods at 100 samples per second).
    """

    fundamental: float
    excited: list[int]
    shares: dict[str, float]
    window: tuple[float, float]


def harmonic_fingerprint(
    t, u, e, fundamental: float, harmonics: int = 15, transient: float = 0.0, excited_level: float = 1e-3
) -> HarmonicFingerprint:
    """The fingerprint (module docstring) of residual ``e`` for input ``u`` on times ``t`` (all 1-D or (1, T, 1)).

    Args:
        fundamental: the drive's fundamental ω in rad/s.
        harmonics: K, the highest harmonic fitted (below the Nyquist frequency).
        transient: seconds at the start left out of the window.
        excited_level: a harmonic of u with amplitude above this share of u's largest is "excited".
    """
    t, u, e = _numpy(t), _numpy(u), _numpy(e)
    keep = t >= t[0] + transient
    t, u, e = t[keep], u[keep], e[keep]
    nyquist = math.pi / float(t[1] - t[0])
    if harmonics * fundamental >= nyquist:
        raise ConfigurationError(f"harmonic {harmonics} of {fundamental:g} rad/s is above the Nyquist {nyquist:.4g} rad/s")
    if t[-1] - t[0] < 2 * math.pi / fundamental:
        raise ConfigurationError("the window holds less than one period of the fundamental; lengthen the record")
    k = np.arange(1, harmonics + 1)
    phase = fundamental * t[:, None] * k[None, :]
    design = np.hstack([np.ones((len(t), 1)), np.cos(phase), np.sin(phase)])
    amplitude = lambda c: np.hypot(c[1 : harmonics + 1], c[harmonics + 1 :])  # noqa: E731
    cu, *_ = np.linalg.lstsq(design, u, rcond=None)
    ce, *_ = np.linalg.lstsq(design, e, rcond=None)
    excited = [int(i) for i in k[amplitude(cu) > excited_level * amplitude(cu).max()]]

    def energy(columns: list[int]) -> float:
        return float(np.sum((design[:, columns] @ ce[columns]) ** 2))

    def columns(numbers: list[int]) -> list[int]:
        return [int(i) for i in numbers] + [int(i) + harmonics for i in numbers]

    total = float(np.sum(e**2))
    odd = [i for i in k if i % 2 and i not in excited]
    even = [i for i in k if not i % 2 and i not in excited]
    shares = {
        "excited": energy(columns(excited)) / total,
        "odd": energy(columns(odd)) / total,
        "even": energy(columns(even)) / total,
        "dc": energy([0]) / total,
    }
    shares["other"] = float(np.sum((e - design @ ce) ** 2)) / total
    return HarmonicFingerprint(fundamental, excited, shares, (float(t[0]), float(t[-1])))
