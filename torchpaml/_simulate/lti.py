r"""Exact simulation of linear time-invariant physics for piecewise-linear inputs.

For $\dot x = A x + B u$, $y = C x + D u$ and an input that is linear between samples spaced $h$
apart (first-order hold), the state obeys exactly

$$ x_{k+1} = \Phi x_k + \Gamma_0 u_k + \Gamma_1 u_{k+1}, \qquad
   \exp\!\begin{pmatrix} A h & B h & 0 \\ 0 & 0 & I \\ 0 & 0 & 0 \end{pmatrix}
   = \begin{pmatrix} \Phi & \Gamma_a & \Gamma_b \\ 0 & I & I \\ 0 & 0 & I \end{pmatrix}, $$

with $\Gamma_1 = \Gamma_b$, $\Gamma_0 = \Gamma_a - \Gamma_b$. The recursion is run as a transfer
function $Y(z) = \big[C\,\mathrm{adj}(zI - \Phi)(\Gamma_0 + z\Gamma_1) + D\,p(z)\big]/p(z)\;U(z)$ whose
characteristic polynomial $p$ and adjugate come from the Faddeev-LeVerrier recursion (matrix
products and traces only, so derivatives stay finite at repeated eigenvalues, e.g. critical
damping). The z-transform of the recursion carries the boundary term $-z\Gamma_1 u_0$, so the
transfer function alone starts from the state $\Gamma_1 u_0$; the free response to
$x_0 - \Gamma_1 u_0$, $\sum_k z^{-k} C\Phi^k (x_0 - \Gamma_1 u_0) = z\,C\,\mathrm{adj}(zI-\Phi)(x_0 - \Gamma_1 u_0)/p(z)$,
is added to start from $x_0$ exactly.

**Zero-order hold.** Where the input is held constant between samples (``hold="zoh"``: a DAC playing
a sampled signal, as in the cascaded-tanks benchmark), the same exponential gives
$x_{k+1} = \Phi x_k + \Gamma_a u_k$: $\Gamma_0 = \Gamma_a$ and $\Gamma_1 = 0$.
"""

from __future__ import annotations

import torch
from torch import nn

from torchpaml._simulate.dynamics import Dynamics
from torchpaml._errors import DataError
from torchpaml._grid import check_hold, uniform_step

from torchpaml._simulate.iir import iir_filter

__all__ = ["discrete_response", "discretize", "exact_step", "foh_exponent", "faddeev_leverrier", "simulate_lti"]


def foh_exponent(A: torch.Tensor, B: torch.Tensor, h: float, ramp: bool = True) -> torch.Tensor:
    r"""The matrix whose exponential holds the first-order-hold discretisation (module docstring),
    (..., n + 2m, n + 2m) for A (..., n, n) and B (..., n, m). ``ramp=False`` leaves out the input ramp's
    constant identity block: the exponent's derivative along a change (dA, dB) is ``foh_exponent(dA, dB, h, False)``."""
    n, m = B.shape[-2:]
    M = torch.zeros(*A.shape[:-2], n + 2 * m, n + 2 * m, dtype=A.dtype, device=A.device)
    M[..., :n, :n] = A * h
    M[..., :n, n : n + m] = B * h
    if ramp:
        M[..., n : n + m, n + m :] = torch.eye(m, dtype=A.dtype, device=A.device)
    return M


def discretize(A: torch.Tensor, B: torch.Tensor, h: float, hold: str = "foh"
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""$(\Phi, \Gamma_0, \Gamma_1)$ of the exact discretisation for the input's ``hold``; A (n, n), B (n, m)."""
    n, m = B.shape
    E = torch.linalg.matrix_exp(foh_exponent(A, B, h))
    Phi, Gamma_a, Gamma_b = E[:n, :n], E[:n, n : n + m], E[:n, n + m :]
    if check_hold(hold) == "zoh":
        return Phi, Gamma_a, torch.zeros_like(Gamma_b)
    return Phi, Gamma_a - Gamma_b, Gamma_b


def faddeev_leverrier(Phi: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Characteristic polynomial and adjugate coefficients of $\Phi$ (n, n).

    Returns ``c`` (n + 1,) with $p(z) = \sum_k c_k z^{n-k}$, $c_0 = 1$, and ``N`` (n, n, n) with
    $\mathrm{adj}(zI - \Phi) = \sum_{k=0}^{n-1} N_k z^{n-1-k}$.
    """
    n = Phi.shape[0]
    eye = torch.eye(n, dtype=Phi.dtype, device=Phi.device)
    N = [eye]
    c = [torch.ones((), dtype=Phi.dtype, device=Phi.device)]
    for k in range(1, n + 1):
        PN = Phi @ N[-1]
        c.append(-torch.trace(PN) / k)
        if k < n:
            N.append(PN + c[-1] * eye)
    return torch.stack(c), torch.stack(N)


def simulate_lti(
    A: torch.Tensor,
    B: torch.Tensor,
    C: torch.Tensor,
    D: torch.Tensor,
    h: float,
    u: torch.Tensor,
    x0: torch.Tensor | None = None,
    hold: str = "foh",
) -> torch.Tensor:
    r"""Exact response of $(A, B, C, D)$ to the input through samples ``u``, held as ``hold`` says.

    Args:
        A, B, C, D: state-space matrices, shapes (n, n), (n, m), (p, n), (p, m).
        h: sampling interval in seconds (uniform).
        u: input samples, shape (batch, time, m).
        x0: initial state, shape (batch, n); zero if omitted.
        hold: ``"foh"`` (linear between samples) or ``"zoh"`` (constant until the next one).

    Returns:
        y: shape (batch, time, p).
    """
    return discrete_response(*discretize(A, B, h, hold), C, D, u, x0)


def discrete_response(
    Phi: torch.Tensor,
    G0: torch.Tensor,
    G1: torch.Tensor,
    C: torch.Tensor,
    D: torch.Tensor,
    u: torch.Tensor,
    x0: torch.Tensor | None = None,
) -> torch.Tensor:
    r"""Response of the discrete system $x_{k+1} = \Phi x_k + \Gamma_0 u_k + \Gamma_1 u_{k+1}$, $y_k = C x_k + D u_k$
    (module docstring), as a transfer function.

    Args:
        Phi, G0, G1, C, D: shapes (n, n), (n, m), (n, m), (p, n), (p, m).
        u: input samples, shape (batch, time, m).
        x0: initial state, shape (batch, n); zero if omitted.

    Returns:
        y: shape (batch, time, p).
    """
    n, m = G0.shape
    p = C.shape[0]
    c, N = faddeev_leverrier(Phi)
    poles = c[1:]
    # numerator of u_i -> y_j over powers z^{n-k}, k = 0..n
    CN = torch.einsum("pn,knl->kpl", C, N)  # (n, p, n)
    num = torch.zeros(n + 1, p, m, dtype=Phi.dtype, device=Phi.device)
    num[:n] = num[:n] + CN @ G1
    num[1:] = num[1:] + CN @ G0
    num = num + c[:, None, None] * D[None]
    y = _through_poles(u, num, poles)
    start = -u[:, 0] @ G1.T if x0 is None else x0 - u[:, 0] @ G1.T
    return y + _free_response(CN, poles, start, u)


def _through_poles(x: torch.Tensor, numerators: torch.Tensor, poles: torch.Tensor) -> torch.Tensor:
    r"""$y_j = \sum_i B_{ji}(q)/p(q)\; x_i$ from rest: x (batch, time, m), numerators (n + 1, p, m) over $q^{-k}$,
    poles the monic $p$'s coefficients after the leading 1, (n,); returns (batch, time, p).

    With one output, one recursion per input channel with its own numerator. With several, every channel
    shares the denominator: one recursion $w_i = x_i/p(q)$ per input channel, and the numerators weigh its
    delays, $y_j = \sum_{i,k} b_{kji}\, w_{i,t-k}$."""
    n, p, m = poles.shape[0], numerators.shape[1], numerators.shape[2]
    if p == 1:
        return iir_filter(x, numerators[:, 0].T, poles.expand(m, n)).sum(-1, keepdim=True)
    w = iir_filter(x, torch.ones(m, 1, dtype=x.dtype, device=x.device), poles.expand(m, n))
    padded = nn.functional.pad(w, (0, 0, n, 0))  # n zeros before the start
    windows = padded.unfold(1, n + 1, 1)  # (batch, time, m, n + 1): w at t - n .. t, a view
    return torch.einsum("btik,kji->btj", windows, numerators.flip(0))


def _free_response(CN: torch.Tensor, poles: torch.Tensor, x0: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    r"""$y_k = C\Phi^k x_0$ as the impulse response of $z\,C\,\mathrm{adj}(zI - \Phi)x_0/p(z)$; (batch, time, p)."""
    n, p = CN.shape[0], CN.shape[1]
    batch, T = u.shape[:2]
    impulse = torch.zeros(1, T, 1, dtype=u.dtype, device=u.device)
    impulse[:, 0] = 1.0
    numerators = torch.einsum("kpl,bl->kbp", CN, x0).reshape(n, batch * p)
    numerators = torch.cat([numerators, torch.zeros_like(numerators[:1])])[..., None]  # (n + 1, batch * p, 1)
    return _through_poles(impulse, numerators, poles).reshape(T, batch, p).transpose(0, 1)


def exact_step(physics: Dynamics, t: torch.Tensor) -> float | None:
    """The sampling interval when ``physics`` takes the exact path (linear physics, uniform grid), else ``None``."""
    if physics.state_space() is None:
        return None
    try:
        return uniform_step(t)
    except DataError:
        return None
