r"""The paper's orthogonal residual: odd Chebyshev polynomials of $u/\alpha$ followed by an LTI filter.

$$ r = \sum_{k=1}^{n} R_k(s)\,\big[T_{2k+1}(u/\alpha)\big], \qquad
   R_k(s) = d_k + \frac{\sum_{j=0}^{m-1} c_{k,j}\, s^j}{D(s)}, $$

a multi-input single-output continuous-time filter of order $m$ with one shared denominator $D$
(the paper writes the same class as $\sum_d A_d r^{(d)} = \sum_{d,k} B_{d,k} \frac{d^d}{dt^d} T_{2k+1}(u/\alpha)$).

*Stability by construction.* $D(s) = (s + \sigma_0)^{[m\ \mathrm{odd}]}\prod_i \big((s + \sigma_i)^2 + \omega_i^2\big)$
with $\sigma_i = \sigma_{\min} + (\Omega - \sigma_{\min})\,\mathrm{sigmoid}(\rho_i)$ and
$\omega_i = \Omega\,\mathrm{sigmoid}(\nu_i)$: every pole lies in the band
$-\Omega < \mathrm{Re}\,s < -\sigma_{\min}$, $|\mathrm{Im}\,s| < \Omega$ for every value of the unconstrained
parameters $(\rho, \nu)$. The margin $\sigma_{\min}$ (default 0.5 1/s: time constants of at most
2 s, the time scale of the paper's mechanics, $\zeta\omega_0 = 1$ 1/s) keeps the fit from parking
poles near the origin, where a near-integrator with a huge DC gain fits the slow drift of one
training record and explodes on the next (seen at $\alpha = 10$ with a margin of 0.1: validation
mismatch up to 10^4 %); the bandwidth $\Omega$ (default 30 rad/s, past the 13th harmonic
of a 1 rad/s drive) keeps the optimiser away from overflowing, meaningless poles.

*Linear in the numerators.* For fixed poles, $r$ is linear in $(c, d)$: the regressors are the
states $s^j/D(s)\,[T_{2k+1}]$ of the controllable canonical realisation plus the features
themselves, which :func:`~torchpaml.fit_chebyshev_hammerstein` exploits (variable projection).

*Orthogonality.* For $u = \alpha\cos(\omega t + \phi)$, $T_{2k+1}(u/\alpha) = \cos((2k+1)(\omega t + \phi))$,
so at steady state $r$ holds only the odd harmonics $3\omega, 5\omega, \dots$: it is orthogonal to
any LTI physics output and to its parameter sensitivities (both pure tones at $\omega$).

*Domain.* $|u| > \alpha$ raises :class:`~torchpaml.DomainError` rather than warning: outside
$[-1, 1]$, $T_{13}$ grows like $(2x)^{13}/2$ (already 140 at $x = 1.2$), so the residual would
extrapolate wildly and the orthogonality argument (which is about inputs of amplitude $\alpha$)
would no longer hold. Pick $\alpha \ge \max|u|$.

*Several channels.* With ``inputs`` > 1 the features are the odd polynomials of each input, $T_{2k+1}(u_i/\alpha)$
($n \cdot$ ``inputs`` of them, no products across inputs, so the orthogonality argument holds input by input);
with ``outputs`` > 1 each output channel has its own numerators and direct terms over one shared denominator.

Shape: ``u`` (batch, time, inputs) on a uniform grid -> ``r`` (batch, time, outputs).
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn

from torchpaml._errors import ConfigurationError, DomainError
from torchpaml._residual.base import AbstractResidual
from torchpaml._simulate.lti import simulate_lti, simulate_lti_states
from torchpaml._grid import uniform_step

__all__ = ["ChebyshevHammerstein", "chebyshev_t"]


def chebyshev_t(x: torch.Tensor, degrees: list[int]) -> torch.Tensor:
    r"""$T_k(x)$ for each k in ``degrees`` by $T_{k+1} = 2xT_k - T_{k-1}$; x (...) -> (..., len(degrees))."""
    top = max(degrees)
    values = [torch.ones_like(x), x]
    for _ in range(2, top + 1):
        values.append(2 * x * values[-1] - values[-2])
    return torch.stack([values[k] for k in degrees], dim=-1)


#: The default filter: order, initial decay rate (1/s), stability margin (1/s) and bandwidth (rad/s).
ORDER, DECAY, MIN_DECAY, BANDWIDTH = 5, 1.5, 0.5, 30.0


def _default_frequencies(order: int) -> list[float]:
    """Initial natural frequencies of the ``order // 2`` pole pairs, geometric from 1 to 6 rad/s."""
    pairs = order // 2
    return [math.exp(v) for v in np.linspace(0.0, math.log(6.0), max(pairs, 1))][:pairs]


class ChebyshevHammerstein(AbstractResidual):
    r"""Chebyshev-Hammerstein residual $r = \sum_k R_k(s)[T_{2k+1}(u/\alpha)]$ (see the module docstring).

    Args:
        alpha: characteristic amplitude $\alpha$; inputs must satisfy $|u| \le \alpha$.
        n: number of odd polynomials $T_3, T_5, \dots, T_{2n+1}$.
        order: order $m$ of the shared denominator $D(s)$.
        decay: initial decay rate $\sigma$ of every pole, 1/s.
        min_decay: stability margin $\sigma_{\min} > 0$ in 1/s; every pole has real part below $-\sigma_{\min}$.
        bandwidth: $\Omega$ in rad/s, bound on the decay rates and frequencies of the poles.
        frequencies: initial natural frequencies of the complex pole pairs, rad/s
            (default: geometric from 1 to 6 rad/s).
        inputs: input channels; each has its own polynomials of $u_i/\alpha$.
        outputs: output channels; each has its own numerators over the shared denominator. The coefficients are
            (features, m + 1) for one output and (outputs, features, m + 1) for several.

    The numerators start at zero, so a fresh residual is the zero model $\mathcal R^{\gamma_0}$.
    """

    def __init__(
        self,
        alpha: float,
        n: int = 6,
        order: int = ORDER,
        *,
        decay: float = DECAY,
        min_decay: float = MIN_DECAY,
        bandwidth: float = BANDWIDTH,
        frequencies: list[float] | None = None,
        inputs: int = 1,
        outputs: int = 1,
    ):
        super().__init__()
        if not alpha > 0:
            raise ConfigurationError(f"alpha must be positive, got {alpha}")
        if not 0 < min_decay < decay < bandwidth:
            raise ConfigurationError(
                f"need 0 < min_decay < decay < bandwidth, got min_decay={min_decay}, decay={decay}, bandwidth={bandwidth}"
            )
        if n < 1 or order < 1 or inputs < 1 or outputs < 1:
            raise ConfigurationError(f"need n, order, inputs and outputs >= 1, got n={n}, order={order}, "
                                     f"inputs={inputs}, outputs={outputs}")
        self.alpha, self.n, self.order = float(alpha), int(n), int(order)
        self.inputs, self.outputs = int(inputs), int(outputs)
        self.min_decay, self.bandwidth = float(min_decay), float(bandwidth)
        self.degrees = [2 * k + 1 for k in range(1, n + 1)]
        pairs = order // 2
        if frequencies is None:
            frequencies = _default_frequencies(order)
        if len(frequencies) != pairs or not all(0 < f < bandwidth for f in frequencies):
            raise ConfigurationError(
                f"order {order} needs {pairs} initial frequencies in (0, bandwidth={bandwidth}), got {frequencies}"
            )
        f64 = dict(dtype=torch.float64)
        decay_share = torch.full((pairs + order % 2,), (decay - min_decay) / (bandwidth - min_decay), **f64)
        self.decay_logit = nn.Parameter(torch.logit(decay_share))
        self.frequency_logit = nn.Parameter(torch.logit(torch.tensor(frequencies, **f64) / bandwidth))
        per_output = () if outputs == 1 else (outputs,)
        self.numerator = nn.Parameter(torch.zeros(*per_output, n * inputs, order, **f64))
        self.direct = nn.Parameter(torch.zeros(*per_output, n * inputs, **f64))

    @classmethod
    def for_sampling(cls, alpha: float, h: float, inputs: int = 1, outputs: int = 1) -> ChebyshevHammerstein:
        r"""The default residual with every rate (decay, margin, bandwidth, initial frequencies) scaled by
        $s = \min\big(1, \pi / (2 h \Omega)\big)$: the default band where the sampling interval ``h`` (s) resolves
        it, else the same band shrunk until $\Omega$ is half the Nyquist frequency $\pi/h$. Beyond Nyquist every
        pole is faster than one sample, the filter states nearly repeat the features, and the nearly collinear
        regressors fit the training record with coefficients that cancel there and not on the next record (the
        cascaded tanks, sampled every 4 s)."""
        scale = min(1.0, math.pi / (2 * h * BANDWIDTH))
        return cls(alpha, decay=scale * DECAY, min_decay=scale * MIN_DECAY, bandwidth=scale * BANDWIDTH,
                   frequencies=[scale * f for f in _default_frequencies(ORDER)], inputs=inputs, outputs=outputs)

    # -- structure ---------------------------------------------------------------------------
    def denominator(self) -> torch.Tensor:
        r"""Monic $D(s)$ coefficients $[1, D_1, \dots, D_m]$ (highest power first), shape (m + 1,)."""
        sigma, omega = self.decay_rates(), self.frequencies()
        poly = torch.ones(1, dtype=torch.float64)
        for i in range(len(omega)):
            section = torch.stack([torch.ones_like(sigma[i]), 2 * sigma[i], sigma[i] ** 2 + omega[i] ** 2])
            poly = _poly_mul(poly, section)
        if self.order % 2:
            poly = _poly_mul(poly, torch.stack([torch.ones_like(sigma[-1]), sigma[-1]]))
        return poly

    def decay_rates(self) -> torch.Tensor:
        r"""Decay rates $\sigma$ of the pole pairs (then of the real pole), 1/s."""
        return self.min_decay + (self.bandwidth - self.min_decay) * torch.sigmoid(self.decay_logit)

    def frequencies(self) -> torch.Tensor:
        r"""Damped frequencies $\omega$ of the pole pairs, rad/s."""
        return self.bandwidth * torch.sigmoid(self.frequency_logit)

    def pole_parameters(self) -> list[nn.Parameter]:
        """The unconstrained parameters the poles depend on (the nonlinear part of the fit)."""
        return [self.decay_logit, self.frequency_logit]

    def poles(self) -> torch.Tensor:
        """Continuous-time poles, complex (m,): all with negative real part."""
        sigma, omega = self.decay_rates().detach(), self.frequencies().detach()
        pairs = [torch.complex(-sigma[i], s * omega[i]) for i in range(len(omega)) for s in (1.0, -1.0)]
        if self.order % 2:
            pairs.append(torch.complex(-sigma[-1], torch.zeros((), dtype=torch.float64)))
        return torch.stack(pairs)

    def features(self, u: torch.Tensor) -> torch.Tensor:
        r"""$T_{2k+1}(u_i/\alpha)$, u (batch, time, inputs) -> (batch, time, n * inputs), input by input; raises
        DomainError if $|u| > \alpha$."""
        if u.shape[-1] != self.inputs:
            raise DomainError(f"the residual takes {self.inputs} input channel(s), got {u.shape[-1]}; build it with "
                              f"inputs={u.shape[-1]}")
        peak = float(u.detach().abs().max()) if u.numel() else 0.0
        if peak > self.alpha * (1 + 1e-9):
            raise DomainError(
                f"the input reaches |u| = {peak:.6g}, beyond the Chebyshev domain alpha = {self.alpha:.6g} of this "
                f"residual; build it with alpha >= {peak:.6g} (e.g. ChebyshevHammerstein(alpha={peak:.4g})) or "
                "scale the input"
            )
        if self.inputs == 1:
            return chebyshev_t(u[..., 0] / self.alpha, self.degrees)
        return torch.cat([chebyshev_t(u[..., i] / self.alpha, self.degrees) for i in range(self.inputs)], dim=-1)

    def regressors(self, t: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        r"""Columns that $r$ is linear in: (batch, time, n, m + 1) = states $s^j/D(s)[T_{2k+1}]$, then $T_{2k+1}$."""
        h = uniform_step(t)
        phi = self.features(u)
        batch, time, n = phi.shape
        D = self.denominator()
        m = self.order
        A = torch.cat([torch.eye(m, dtype=torch.float64)[1:], -D.flip(0)[:m][None]])  # companion form
        B = torch.zeros(m, 1, dtype=torch.float64)
        B[-1, 0] = 1.0
        states = simulate_lti_states(A, B, h, phi.transpose(1, 2).reshape(-1, time, 1))
        states = states.reshape(batch, n, time, m).transpose(1, 2)
        return torch.cat([states, phi[..., None]], dim=-1)

    def coefficients(self) -> torch.Tensor:
        """The linear parameters as (features, m + 1), or (outputs, features, m + 1) for several outputs: numerator
        $c_{k,0..m-1}$ then direct term $d_k$."""
        return torch.cat([self.numerator, self.direct[..., None]], dim=-1)

    def set_coefficients(self, coefficients: torch.Tensor) -> None:
        """Assign the linear parameters (inverse of :meth:`coefficients`)."""
        with torch.no_grad():
            self.numerator.copy_(coefficients[..., : self.order])
            self.direct.copy_(coefficients[..., self.order])

    def response(self, t: torch.Tensor, u: torch.Tensor, coefficients: torch.Tensor) -> torch.Tensor:
        r"""$r$ for the linear parameters ``coefficients`` (as :meth:`coefficients` lays them out), (batch, time,
        outputs): per output, the multi-input filter $\sum_k R_k(s)[T_{2k+1}]$, as the :meth:`regressors` times the
        coefficients, the realisation the fit projects on. Differentiable in the poles and in ``coefficients``."""
        regressors = self.regressors(t, u)  # (batch, time, features, m + 1)
        if self.outputs == 1:
            return torch.einsum("btkj,kj->bt", regressors, coefficients)[..., None]
        return torch.einsum("btkj,okj->bto", regressors, coefficients)

    def observable_response(self, t: torch.Tensor, u: torch.Tensor, coefficients: torch.Tensor) -> torch.Tensor:
        r""":meth:`response`'s transfer functions in observable canonical form ($A^\top$, the numerators as its input
        matrix, $e_m^\top$, the direct terms), one $m$-state recursion driven by every feature at once instead of one
        per feature: cheaper to differentiate in the poles, the pole search's derivative. Both forms are simulated by
        the same exact recursion on their states (:func:`~torchpaml._simulate.lti.simulate_lti`) and agree to
        rounding, also with poles near $z = 1$ (tested at h = 1 ms). (batch, time, outputs)."""
        h = uniform_step(t)
        phi = self.features(u)
        m = self.order
        A = torch.cat([torch.eye(m, dtype=torch.float64)[1:], -self.denominator().flip(0)[:m][None]])
        C = torch.zeros(1, m, dtype=torch.float64)
        C[0, -1] = 1.0
        per_output = coefficients[None] if self.outputs == 1 else coefficients
        return torch.cat([simulate_lti(A.T, c[:, :m].T, C, c[None, :, m], h, phi) for c in per_output], dim=-1)

    def forward(self, t: torch.Tensor, u: torch.Tensor, y_physics: torch.Tensor | None = None) -> torch.Tensor:
        return self.response(t, u, self.coefficients())


def _poly_mul(p: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """Product of polynomials given by coefficient vectors (highest power first)."""
    out = torch.zeros(len(p) + len(q) - 1, dtype=p.dtype)
    for i in range(len(q)):
        out = out + nn.functional.pad(p * q[i], (i, len(q) - 1 - i))
    return out
