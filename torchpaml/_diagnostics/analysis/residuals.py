r"""Residual analysis like MATLAB's ``resid``: is $e = y - \hat y$ white, and independent of the input?

With $N$ samples, the normalised autocorrelation $\rho_{ee}(\tau) = r_{ee}(\tau)/r_{ee}(0)$ of a white
residual lies within $\pm z_{1-\beta/2}/\sqrt N$ with probability $1 - \beta$ at every lag $\tau \ne 0$.

The independence test cross-correlates the residual with the input after **prewhitening** (Box & Jenkins; SAS's
``PROC ARIMA``, astsa's ``pre.white``): an AR model of order $p$ = ``lags`` fitted to $u$ by Yule-Walker,
$A(q)\,u = w$, whitens the input, and the same filter is applied to the residual, $e' = A(q)\,e$ (the first $p$
samples dropped). Then $\rho_{u'e'}(\tau) = r_{e'u'}(\tau)/\sqrt{r_{u'u'}(0)\,r_{e'e'}(0)}$ of an $e$ independent of
$u$ lies within $\pm z_{1-\beta/2}\sqrt{P/N'}$, with Bartlett's $P = \sum_{|k| \le L} (1 - \tfrac{|k|}{L+1})\,
\rho_{u'u'}(k)\,\rho_{e'e'}(k)$, which is 1 for the whitened input. Without prewhitening two smooth, independent
signals correlate strongly by chance, and the band that says so ($\pm 0.4$ to $\pm 0.6$ on 600 samples) is crossed by
no missing effect. Here $r_{ab}(\tau) = \frac1N\sum_t a(t+\tau)\,b(t)$ after removing the means. A correlation
outside the bounds says the model misses dynamics: $\rho_{ee}$ shows unmodelled dynamics of any kind, and
$\rho_{u'e'}$ at positive lags shows dynamics from the input that the model does not reproduce.

An effect size beside the bounds: the share of the residual's variance that the best causal linear filter
of the input over lags 0..L explains (the Wiener filter $a$ of the normal equations $R_{uu} a = r_{eu}$,
$R_{uu}$ the Toeplitz matrix of $r_{uu}(0..L)$), ``linear_share`` $= a^\top r_{eu} / r_{ee}(0) \in [0, 1]$.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from torchpaml._errors import ConfigurationError
from scipy import linalg, signal as sps
from scipy import stats

__all__ = ["ResidualAnalysis", "residual_analysis"]


def _numpy(x) -> np.ndarray:
    return x.detach().cpu().numpy().reshape(-1) if isinstance(x, torch.Tensor) else np.asarray(x, float).reshape(-1)


@dataclass
class ResidualAnalysis:
    """Correlations and their bounds (module docstring): the residual's autocorrelation, and its cross-correlation
    with the input after prewhitening. ``lags`` (L+1,) from 0; ``cross_lags`` (2L+1,)."""

    lags: np.ndarray
    autocorrelation: np.ndarray
    autocorrelation_bound: float
    cross_lags: np.ndarray
    cross_correlation: np.ndarray
    cross_correlation_bound: float
    confidence: float
    linear_share: float

    @property
    def autocorrelation_outside(self) -> np.ndarray:
        """Lags τ ≥ 1 where |ρ_ee(τ)| exceeds the bound."""
        outside = np.abs(self.autocorrelation) > self.autocorrelation_bound
        return self.lags[1:][outside[1:]]

    @property
    def cross_correlation_outside(self) -> np.ndarray:
        """Lags τ where |ρ_ue(τ)| exceeds the bound."""
        return self.cross_lags[np.abs(self.cross_correlation) > self.cross_correlation_bound]


def residual_analysis(u, e, lags: int = 25, confidence: float = 0.99) -> ResidualAnalysis:
    """Correlations of the residual ``e`` and the input ``u`` (1-D or (1, time, 1)) for lags 0..L and -L..L."""
    u, e = _numpy(u), _numpy(e)
    n = len(e)
    if len(u) != n or n <= 2 * lags:
        raise ConfigurationError(f"need u and e of one length above 2*lags = {2 * lags}, got {len(u)} and {n}")
    u, e = u - u.mean(), e - e.mean()

    def correlation(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # r_ab(tau) for tau = -(n-1)..(n-1)
        return sps.correlate(a, b, mode="full", method="fft") / n

    r_ee, r_uu, r_ue = correlation(e, e), correlation(u, u), correlation(e, u)
    zero = n - 1
    rho_ee = r_ee / r_ee[zero]
    z = float(stats.norm.ppf(0.5 + confidence / 2))
    cross, bound = _prewhitened_cross_correlation(u, e, r_uu[zero : zero + lags + 1], lags, z)
    return ResidualAnalysis(
        lags=np.arange(lags + 1),
        autocorrelation=rho_ee[zero : zero + lags + 1],
        autocorrelation_bound=z / np.sqrt(n),
        cross_lags=np.arange(-lags, lags + 1),
        cross_correlation=cross,
        cross_correlation_bound=bound,
        confidence=confidence,
        linear_share=_linear_share(r_uu[zero : zero + lags + 1], r_ue[zero : zero + lags + 1], r_ee[zero]),
    )


def _prewhitened_cross_correlation(u: np.ndarray, e: np.ndarray, r_uu: np.ndarray, lags: int, z: float
                                   ) -> tuple[np.ndarray, float]:
    """$\rho_{u'e'}(\tau)$ for $\tau = -L..L$ and its bound (module docstring): ``u`` and ``e`` (N,) without their
    means, ``r_uu`` the input's autocovariance at lags 0..L. A zero input or residual: zeros, and the white bound."""
    if r_uu[0] <= 0 or not np.any(e):
        return np.zeros(2 * lags + 1), z / np.sqrt(len(e))
    ar = linalg.solve_toeplitz(r_uu[:-1], r_uu[1:])  # Yule-Walker: u(t) = sum_k ar_k u(t - k) + w(t)
    whiten = np.concatenate([[1.0], -ar])
    u_w, e_w = (sps.lfilter(whiten, [1.0], x)[lags:] for x in (u, e))
    u_w, e_w = u_w - u_w.mean(), e_w - e_w.mean()
    n = len(e_w)
    r = {key: sps.correlate(a, b, mode="full", method="fft") / n
         for key, (a, b) in {"ee": (e_w, e_w), "uu": (u_w, u_w), "eu": (e_w, u_w)}.items()}
    zero = n - 1
    window = 1 - np.abs(np.arange(-lags, lags + 1)) / (lags + 1)
    around = slice(zero - lags, zero + lags + 1)
    bartlett = float(np.sum(window * r["ee"][around] * r["uu"][around]) / (r["ee"][zero] * r["uu"][zero]))
    cross = r["eu"][around] / np.sqrt(r["uu"][zero] * r["ee"][zero])
    return cross, z * np.sqrt(max(bartlett, 1.0 / n) / n)


def _linear_share(r_uu: np.ndarray, r_eu: np.ndarray, r_ee: float) -> float:
    """The Wiener filter's explained share $a^\top r_{eu} / r_{ee}(0)$ (module docstring); 0 for a zero input."""
    if r_uu[0] <= 0 or r_ee <= 0:
        return 0.0
    taps = linalg.solve_toeplitz(r_uu, r_eu)
    return float(np.clip(taps @ r_eu / r_ee, 0.0, 1.0))
