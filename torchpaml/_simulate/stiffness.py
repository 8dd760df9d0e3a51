r"""Stiffness: whether an explicit step is stable along a trajectory, and the substeps that make it so.

RK4 is stable on $\dot x = \lambda x$ while $|h\lambda| \lesssim 2.5$ (its stability region holds the left
half-disc of that radius; it reaches 2.79 on the negative real axis). Along a trajectory $x_k$ the
physics' local rates are the eigenvalues of $J_k = \partial f/\partial x\,(t_k, x_k, u_k)$, so RK4 at $m$
substeps per sample interval $h$ is stable where

$$ \sigma = \max_k\, h_k\,\rho(J_k) \le 2.5\, m, $$

$\rho$ the spectral radius. The step doubling alone cannot see a violation when the physics bounds the
state (a spill above a rim: the unstable step throws the level below the rim, where it is slow), because
the wrong outputs at $m$ and $2m$ can agree. The stiffness $\sigma$ is checked first, by the fit's step
check and by :func:`~torchpaml.simulate`'s RK4 step doubling; beyond
:data:`~torchpaml._simulate.step_control.MAX_SUBSTEPS` the physics is stiff for RK4, and the implicit,
L-stable TR-BDF2 (no such limit) takes over where the solver is the default.
"""

from __future__ import annotations

import math
import torch

from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.method import Method
from torchpaml._errors import ResolutionError
from torchpaml._simulate.step_control import MAX_SUBSTEPS


__all__ = ["RK4_STABILITY", "STIFF_SUBSTEPS", "stable_substeps", "stiffness"]

#: RK4 substeps beyond which the default solver calls the physics stiff and integrates it with TR-BDF2: where
#: stability alone needs more RK4 steps than this, one or two TR-BDF2 steps (a few physics calls each) cost less.
STIFF_SUBSTEPS = 8
#: The most samples (of every row together) at which the rates are evaluated, evenly spaced.
POINTS = 4096
#: The share of the samples whose rates set $\sigma$: the largest rate but for the steepest 1 %.
QUANTILE = 0.99
#: Relative step of the forward differences of $J$ (the estimate needs its size, not its digits).
DIFFERENCE = 1e-7
#: $|h\lambda|$ up to which RK4 is stable (module docstring; ``RK4.stability``); implicit methods have no limit.
RK4_STABILITY = 2.5


def stiffness(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, states: torch.Tensor) -> float:
    r"""$\sigma = \max_k h_k\,\rho(J_k)$ (module docstring) over the samples of ``states`` (batch, time, n), driven by
    ``u`` (batch, time, n_input) on the grid ``t`` (time,), at most :data:`POINTS` of them evenly spaced, as its
    :data:`QUANTILE` (a square root at an empty tank is infinitely steep at one sample, which does not make the
    record stiff); 0 for fewer than two samples."""
    if len(t) < 2:
        return 0.0
    n, m = states.shape[-1], u.shape[-1]
    stride = max(1, math.ceil(states.shape[0] * (len(t) - 1) / POINTS))
    rows = states[:, :-1].reshape(-1, n).detach()[::stride]
    times, inputs = t[:-1].repeat(states.shape[0])[::stride], u[:, :-1].reshape(-1, m)[::stride]
    steps = torch.diff(t).repeat(states.shape[0])[::stride]
    delta = DIFFERENCE * rows.abs().amax(dim=0).clamp(min=1.0)  # (n,)
    shifted = (rows[None] + torch.diag(delta)[:, None]).reshape(-1, n)  # n copies, one state moved in each
    with torch.no_grad():
        rates = physics.derivative(times.repeat(n + 1), torch.cat([rows, shifted]),
                                   inputs.repeat(n + 1, 1)).reshape(n + 1, -1, n)
    J = ((rates[1:] - rates[:1]) / delta[:, None, None]).permute(1, 2, 0)  # (points, n, n): d f_i / d x_j
    radius = torch.linalg.eigvals(J.nan_to_num(0.0, 0.0, 0.0)).abs().amax(dim=-1)
    return float(torch.quantile(radius * steps, QUANTILE))


def stable_substeps(solver: Method, sigma: float, most: int = MAX_SUBSTEPS) -> int:
    """The substeps of ``solver`` (whole) or the least power-of-two multiple of them at which its step is stable
    for stiffness ``sigma``; the substeps themselves for an implicit method. Raises
    :class:`~torchpaml.ResolutionError` where that is more than ``most``: the physics is stiff for the
    method (the default solver then takes TR-BDF2 beyond :data:`STIFF_SUBSTEPS`)."""
    m = solver.substeps
    limit = solver.stability
    if limit is None or sigma <= limit * m:
        return m
    needed = m * 2 ** math.ceil(math.log2(sigma / (limit * m)))
    if needed > most:
        name = type(solver).__name__
        raise ResolutionError(
            f"the physics is stiff for {name}: a rate of the model times the sample interval reaches {sigma:.3g} "
            f"along the trajectory, and {name} is stable up to {limit:g} per substep, which needs {needed} substeps "
            f"per sample, more than {most}. Integrate with solver=TRBDF2() (implicit, L-stable), bound that "
            "rate to what the sampling resolves, or sample faster")
    return needed
