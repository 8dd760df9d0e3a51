"""One entry point that simulates any physics, by the solver passed in (:mod:`~torchpaml._simulate.solvers`): it checks
the arguments, and the solver integrates (:meth:`~torchpaml.Solver.integrate`)."""

from __future__ import annotations

import torch

from torchpaml._errors import ConfigurationError, DataError
from torchpaml._grid import check_hold
from torchpaml._physics.base import AbstractPhysics, complete_state
from torchpaml._simulate.solvers import Auto, Solver
from torchpaml._simulate.warm import WarmStart

__all__ = ["simulate"]


def simulate(
    physics: AbstractPhysics,
    t: torch.Tensor,
    u: torch.Tensor,
    x0: torch.Tensor | None = None,
    *,
    solver: Solver | None = None,
    warm: WarmStart | None = None,
    hold: str = "foh",
    knots: torch.Tensor | None = None,
    blowup: float = 1e8,
) -> torch.Tensor:
    r"""Simulate $y = \mathcal H^\theta[u]$ for the input through the samples, held as ``hold`` says.

    Args:
        physics: an :class:`~torchpaml.AbstractPhysics`.
        t: sample times in s, shape (time,), shared by the batch.
        u: input samples, shape (batch, time, n_input), float64.
        x0: initial state (batch, n_state), or of the base's states only (``physics + effect``: the effects' own
            states then start at their declared values, :func:`~torchpaml.complete_state`); rest if omitted.
        solver: how to integrate (:mod:`~torchpaml._simulate.solvers`): :class:`~torchpaml.Auto` (the default:
            exact for linear physics on a uniform grid, else RK4 to ``rtol``, else, for stiff physics, TR-BDF2),
            :class:`~torchpaml.Exact`, :class:`~torchpaml.RK4`, :class:`~torchpaml.TRBDF2` or
            :class:`~torchpaml.Dopri5`. A fixed-step solver with ``substeps="auto"`` doubles its substeps until
            halving the step moves the output by at most ``rtol`` of its size
            (:func:`~torchpaml._simulate.step_control.simulate_to_tolerance`), and raises
            :class:`~torchpaml.ResolutionError` when that takes more than 64. A fit's
            ``PhysicsEstimate.solver`` simulates the fitted model as it was fitted.
        warm: a :class:`~torchpaml.WarmStart` kept by the caller between simulations of the same record
            (RK4, TR-BDF2): Newton starts from the states the previous one stored there. The result does not
            depend on it.
        hold: ``"foh"`` (the input linear between samples) or ``"zoh"`` (held constant until the next
            sample); the exact path and the fixed-step solvers take either, ``Dopri5`` ``"foh"`` only.
        knots: times where the input's slope jumps, stepped on by ``Dopri5`` (see
            :func:`~torchpaml._simulate.ode.simulate_ode`).
        blowup: an output beyond this magnitude raises :class:`SimulationError`.

    Returns:
        y: shape (batch, time, n_output). Differentiable in the physical parameters and ``u``.
    """
    if u.dim() != 3 or u.shape[1] != t.shape[-1]:
        raise DataError(f"u must have shape (batch, time={t.shape[-1]}, channel), got {tuple(u.shape)}")
    if isinstance(x0, Solver):
        raise ConfigurationError(f"simulate's fourth argument is the initial state; pass the solver by name: solver={x0!r}")
    solver = Auto() if solver is None else solver
    if not isinstance(solver, Solver):
        raise ConfigurationError(f"solver must be one of torchpaml's solvers (Auto(), Exact(), RK4(), TRBDF2(), Dopri5()), "
                        f"got {solver!r}")
    x0 = complete_state(physics, x0, u.shape[0]).to(u)
    return solver.integrate(physics, t, u, x0, warm=warm, hold=check_hold(hold), knots=knots, blowup=blowup)
