"""One entry point that simulates any physics: exact for linear physics, RK4 to a tolerance otherwise, or torchdiffeq."""

from __future__ import annotations

from typing import Literal

import torch

from torchpaml._errors import DataError, SimulationError
from torchpaml._physics.base import AbstractPhysics, complete_state
from torchpaml._grid import check_hold, uniform_step
from torchpaml._simulate.lti import exact_step, simulate_lti
from torchpaml._simulate.ode import simulate_ode
from torchpaml._simulate.warm import WarmStart
from torchpaml._simulate.shooting import SEGMENT_STEPS, simulate_rk4
from torchpaml._simulate.step_control import simulate_to_tolerance

__all__ = ["ADAPTIVE_RTOL", "RK4_RTOL", "checked_output", "simulate"]

#: Default ``rtol`` of RK4's step doubling: the output's relative error, as scipy's ``solve_ivp`` defaults to
#: (the gap bounds the error of the returned, finer output; measured 15 to 20 times smaller on smooth physics).
RK4_RTOL = 1e-3
#: Default ``rtol`` of torchdiffeq's adaptive solvers (per step).
ADAPTIVE_RTOL = 1e-7


def simulate(
    physics: AbstractPhysics,
    t: torch.Tensor,
    u: torch.Tensor,
    x0: torch.Tensor | None = None,
    *,
    method: str = "auto",
    rtol: float | None = None,
    atol: float = 1e-9,
    adjoint: bool = False,
    max_num_steps: int = 1_000_000,
    knots: torch.Tensor | None = None,
    substeps: int | Literal["auto"] = "auto",
    segment: int = SEGMENT_STEPS,
    blowup: float = 1e8,
    warm: WarmStart | None = None,
    hold: str = "foh",
) -> torch.Tensor:
    r"""Simulate $y = \mathcal H^\theta[u]$ for the input through the samples, held as ``hold`` says.

    Args:
        physics: an :class:`~torchpaml._physics.AbstractPhysics`.
        t: sample times in s, shape (time,), shared by the batch.
        u: input samples, shape (batch, time, n_input), float64.
        x0: initial state (batch, n_state), or of the base's states only (``physics + effect``: the effects' own
            states then start at their declared values, :func:`~torchpaml._physics.complete_state`); rest if omitted.
        method: ``"auto"`` (exact for linear physics on a uniform grid, else ``"rk4"``), ``"exact"``,
            ``"rk4"`` (fixed-step RK4 on the sample grid, parallel in time:
            :func:`~torchpaml._simulate.shooting.simulate_rk4`), or any other torchdiffeq method name
            (``"dopri5"``: adaptive, with error control).
        rtol: relative tolerance. RK4 with ``substeps="auto"``: of the whole output, by step doubling (default
            :data:`RK4_RTOL`); an adaptive torchdiffeq solver: of each step (default :data:`ADAPTIVE_RTOL`).
        atol: absolute tolerance of an adaptive torchdiffeq solver.
        adjoint: differentiate a torchdiffeq solve by the adjoint method.
        max_num_steps: step limit of an adaptive torchdiffeq solver.
        substeps: RK4 steps per sample interval (``"rk4"``). ``"auto"`` (default): from the model's
            ``substeps`` (1, or what :func:`~torchpaml._fit.fit_physics` resolved), doubled until halving the
            step moves the output by at most ``rtol`` of its size, and the output at the finer step returned
            (:func:`~torchpaml._simulate.step_control.simulate_to_tolerance`); raises
            :class:`~torchpaml._errors.ResolutionError` when that takes more than 64. A number: that many,
            unchecked. Calling the model, ``physics(t, u)``, simulates at its own ``substeps``.
        segment: RK4 steps per shooting segment (``"rk4"``).
        knots: times where the input's slope jumps, stepped on by adaptive solvers (see
            :func:`~torchpaml._simulate.ode.simulate_ode`); the exact path needs none.
        blowup: an output beyond this magnitude raises :class:`SimulationError`.
        warm: a :class:`~torchpaml.WarmStart` kept by the caller between simulations of the same record
            (``"rk4"``): Newton starts from the states the previous one stored there. The result does not
            depend on it.
        hold: ``"foh"`` (the input linear between samples) or ``"zoh"`` (held constant until the next
            sample); the exact path and ``"rk4"`` take either, torchdiffeq's solvers ``"foh"`` only.

    Returns:
        y: shape (batch, time, n_output). Differentiable in the physical parameters and ``u``.
    """
    if u.dim() != 3 or u.shape[1] != t.shape[-1]:
        raise DataError(f"u must have shape (batch, time={t.shape[-1]}, channel), got {tuple(u.shape)}")
    x0 = complete_state(physics, x0, u.shape[0]).to(u)
    if check_hold(hold) == "zoh" and method not in ("auto", "exact", "rk4"):
        raise ValueError(f"hold='zoh' is simulated by the exact path and by 'rk4', not by {method!r}, whose "
                         "interpolant is first-order; use method='rk4' (with substeps=) or 'auto'")
    if method == "exact":
        if physics.state_space() is None:
            raise ValueError(f"method='exact' needs linear physics; {type(physics).__name__} is nonlinear. Use 'rk4'")
        h = uniform_step(t)  # raises, naming the spacing, on a non-uniform grid
    else:
        h = exact_step(physics, t) if method == "auto" else None
    if h is not None:
        return checked_output(simulate_lti(*physics.state_space(), h, u, x0, hold), t, blowup)
    if method in ("auto", "rk4"):
        def run(m: int) -> torch.Tensor:
            states = simulate_rk4(physics, t, u, x0, warm, substeps=m, segment=segment, hold=hold)
            return checked_output(physics.output(states, u), t, blowup)

        if substeps != "auto":
            if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
                raise ValueError(f"substeps must be 'auto' (RK4 to rtol) or a whole number of RK4 steps per sample "
                                 f"interval, at least 1; got {substeps!r}")
            return run(substeps)
        warm = WarmStart() if warm is None else warm  # the accepted step's solve starts the differentiable one
        step = float((t[-1] - t[0]) / max(len(t) - 1, 1))
        return simulate_to_tolerance(run, physics.substeps, RK4_RTOL if rtol is None else rtol, step)[0]
    states = simulate_ode(
        physics, t, u, x0, method=method, rtol=ADAPTIVE_RTOL if rtol is None else rtol, atol=atol, adjoint=adjoint, max_num_steps=max_num_steps,
        knots=knots,
    )
    return checked_output(physics.output(states, u), t, blowup)


def checked_output(y: torch.Tensor, t: torch.Tensor, blowup: float = 1e8) -> torch.Tensor:
    """``y`` itself; raises :class:`SimulationError` naming the time where it is non-finite or beyond ``blowup``."""
    bad = ~torch.isfinite(y) | (y.abs() > blowup)
    if bool(bad.any()):
        k = int(bad.any(dim=0).any(dim=-1).nonzero()[0])
        raise SimulationError(
            f"the simulated output blew up (non-finite or |y| > {blowup:g}) at t = {float(t[k]):.4g} s; the "
            "parameters are probably unstable or unphysical (e.g. negative damping, wrong sign of stiffness), "
            "or the input is far larger than the physics is meant for"
        )
    return y
