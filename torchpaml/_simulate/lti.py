r"""Exact simulation of linear time-invariant physics for piecewise-linear inputs.

For $\dot x = A x + B u$, $y = C x + D u$ and an input that is linear between samples spaced $h$
apart (first-order hold), the state obeys exactly

$$ x_{k+1} = \Phi x_k + \Gamma_0 u_k + \Gamma_1 u_{k+1}, \qquad
   \exp\!\begin{pmatrix} A h & B h & 0 \\ 0 & 0 & I \\ 0 & 0 & 0 \end{pmatrix}
   = \begin{pmatrix} \Phi & \Gamma_a & \Gamma_b \\ 0 & I & I \\ 0 & 0 & I \end{pmatrix}, $$

with $\Gamma_1 = \Gamma_b$, $\Gamma_0 = \Gamma_a - \Gamma_b$, from $x_0$. The recursion runs on the states
themselves, stepped in C (:mod:`~torchpaml._simulate.compiled_recurrence`; the parallel scan of
:func:`~torchpaml._simulate.scan.constant_recurrence` where the machine cannot compile): its roundings stay those of
a few products per step, however close the poles sit to $z = 1$. A transfer function's direct form would not: at a fine sampling interval its
$n$ poles cluster within $|\lambda| h$ of $z = 1$ and its recursion amplifies each rounding by about
$(|\lambda| h)^{-n}$ (the Chebyshev residual's fifth-order filter at $h = 1$ ms: inputs perturbed by $10^{-12}$
moved its states by $2 \cdot 10^{-3}$).

**Zero-order hold.** Where the input is held constant between samples (``hold="zoh"``: a DAC playing
a sampled signal, as in the cascaded-tanks benchmark), the same exponential gives
$x_{k+1} = \Phi x_k + \Gamma_a u_k$: $\Gamma_0 = \Gamma_a$ and $\Gamma_1 = 0$.
"""

from __future__ import annotations

import torch

from torchpaml._simulate.dynamics import Dynamics
from torchpaml._errors import DataError
from torchpaml._grid import check_hold, uniform_step
from torchpaml._simulate.compiled_recurrence import sequential_forced
from torchpaml._simulate.scan import constant_recurrence

__all__ = ["discrete_response", "discrete_states", "discretize", "exact_step", "foh_exponent", "simulate_lti",
           "simulate_lti_states"]


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
    return simulate_lti_states(A, B, h, u, x0, hold) @ C.T + u @ D.T


def simulate_lti_states(A: torch.Tensor, B: torch.Tensor, h: float, u: torch.Tensor, x0: torch.Tensor | None = None,
                        hold: str = "foh") -> torch.Tensor:
    """The states of :func:`simulate_lti`, (batch, time, n): its response with $C = I$, $D = 0$."""
    return discrete_states(*discretize(A, B, h, hold), u, x0)


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
    from $x_0$ (module docstring).

    Args:
        Phi, G0, G1, C, D: shapes (n, n), (n, m), (n, m), (p, n), (p, m).
        u: input samples, shape (batch, time, m).
        x0: initial state, shape (batch, n); zero if omitted.

    Returns:
        y: shape (batch, time, p).
    """
    return discrete_states(Phi, G0, G1, u, x0) @ C.T + u @ D.T


def discrete_states(Phi: torch.Tensor, G0: torch.Tensor, G1: torch.Tensor, u: torch.Tensor,
                    x0: torch.Tensor | None = None) -> torch.Tensor:
    r"""The states of :func:`discrete_response`, (batch, time, n) (module docstring): where no derivative is recorded,
    one loop in C that forms each drive as it steps
    (:func:`~torchpaml._simulate.compiled_recurrence.sequential_forced`); else the drives
    $\Gamma_0 u_k + \Gamma_1 u_{k+1}$, then :func:`~torchpaml._simulate.scan.constant_recurrence` on them."""
    if x0 is None:
        x0 = torch.zeros(u.shape[0], Phi.shape[0], dtype=Phi.dtype, device=Phi.device)
    recorded = torch.is_grad_enabled() and any(x.requires_grad for x in (Phi, G0, G1, u, x0))
    states = None if recorded else sequential_forced(Phi, G0, G1, u, x0)
    if states is not None:
        return states
    drive = (u @ G0.T)[:, :-1] + (u @ G1.T)[:, 1:]  # (batch, time - 1, n)
    return constant_recurrence(Phi, drive, x0)


def exact_step(physics: Dynamics, t: torch.Tensor) -> float | None:
    """The sampling interval when ``physics`` takes the exact path (linear physics, uniform grid), else ``None``."""
    if physics.state_space() is None:
        return None
    try:
        return uniform_step(t)
    except DataError:
        return None
