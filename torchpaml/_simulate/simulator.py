"""The entry points that simulate any physics by the solver passed in (:mod:`~torchpaml._simulate.solvers`): they
check the arguments, and the solver integrates (:meth:`~torchpaml.Solver.integrate`) or differentiates
(:meth:`~torchpaml.Solver.jacobian`)."""

from __future__ import annotations

from collections.abc import Sequence

import torch

from torchpaml._errors import ConfigurationError, DataError
from torchpaml._grid import check_hold
from torchpaml._simulate.blowup import BLOWUP, checked_output
from torchpaml._simulate.dynamics import Dynamics, complete_state
from torchpaml._simulate.sensitivity import raw_parameters
from torchpaml._simulate.solvers import Auto, Solver
from torchpaml._simulate.warm import WarmStart

__all__ = ["checked_solver", "output_jacobian", "simulate"]


def simulate(
    physics: Dynamics,
    t: torch.Tensor,
    u: torch.Tensor,
    x0: torch.Tensor | None = None,
    *,
    solver: Solver | None = None,
    warm: WarmStart | None = None,
    hold: str = "foh",
    knots: torch.Tensor | None = None,
    blowup: float = BLOWUP,
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
    _check_finite("u", u)
    solver = checked_solver(solver)
    x0 = complete_state(physics, x0, u.shape[0]).to(u)
    _check_finite("x0", x0)
    return solver.integrate(physics, t, u, x0, warm=warm, hold=check_hold(hold), knots=knots, blowup=blowup)


def _check_finite(name: str, values: torch.Tensor) -> None:
    """A clear :class:`~torchpaml.DataError` for NaN or infinite ``values``, which would otherwise reach the solver and
    read as a simulation that blew up."""
    bad = ~torch.isfinite(values.detach())
    if bool(bad.any()):
        first = [int(i) for i in bad.nonzero()[0]]
        raise DataError(f"{name} has {int(bad.sum())} NaN/inf value(s), first at index {first}; drop or interpolate "
                        "those samples before simulating")


def checked_solver(solver: Solver | None) -> Solver:
    """``solver``, or the default ``Auto()``; a clear error for anything that is not a :class:`~torchpaml.Solver`."""
    if solver is None:
        return Auto()
    if not isinstance(solver, Solver):
        raise ConfigurationError(f"solver must be a torchpaml Solver (Auto(), Exact(), RK4(), TRBDF2(), Dopri5(), or a "
                                 f"subclass of Solver), got {solver!r}")
    return solver


def output_jacobian(
    physics: Dynamics, names: Sequence[str], t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor | None = None,
    warm: WarmStart | None = None, initial_state: bool = False, hold: str = "foh", solver: Solver | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Output and its Jacobian in the raw parameters ``names``, by the solver's sensitivities
    (:meth:`~torchpaml.Solver.jacobian`; :mod:`~torchpaml._simulate.sensitivity`).

    Args:
        physics: the model.
        names: physical parameter names, p of them.
        t: (time,); u: (batch, time, n_input); x0: (batch, n_state), rest if omitted.
        warm: a :class:`~torchpaml.WarmStart` the caller keeps between calls on the same record (a fit's
            iterations): the shooting engine stores its converged states in it and starts the next Newton solve
            from them.
        initial_state: also differentiate in ``x0``.
        hold: ``"foh"`` or ``"zoh"``, how the input moves between samples (:func:`~torchpaml.simulate`).
        solver: the solver at whose resolution to differentiate (:meth:`~torchpaml.Solver.states`): a fit's
            ``PhysicsEstimate.solver``, or ``Auto(start=...)``; default ``Auto()`` (exact for linear physics on a
            uniform grid, else RK4 at one substep per sample).

    Returns:
        y (batch, time, n_output) and J (batch, time, n_output, p), or (..., p + n_state) with
        ``initial_state``: the parameters' columns first. Raises
        :class:`~torchpaml.SimulationError` if the output blows up.
    """
    x0 = complete_state(physics, x0, u.shape[0]).to(u)
    raw = raw_parameters(physics, names)
    if not raw and not initial_state:
        raise ConfigurationError(f"output_jacobian needs at least one parameter name; {physics.display_name} has "
                                 f"{sorted(physics.physical_parameters())}")
    y, J = checked_solver(solver).jacobian(physics, raw, t, u, x0, warm=warm, hold=check_hold(hold),
                                     initial_state=initial_state)
    return checked_output(y, t), J
