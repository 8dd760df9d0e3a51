"""One entry point that simulates any physics, by the solver passed in (:mod:`~torchpaml._simulate.solvers`)."""

from __future__ import annotations

import torch

from torchpaml._errors import DataError, ResolutionError, SimulationError
from torchpaml._physics.base import AbstractPhysics, complete_state
from torchpaml._grid import check_hold, uniform_step
from torchpaml._simulate.lti import exact_step, simulate_lti
from torchpaml._simulate.ode import simulate_ode
from torchpaml._simulate.shooting import base_guess, simulate_shooting
from torchpaml._simulate.solvers import RK4, TRBDF2, Auto, Dopri5, Exact, FixedStep, Solver
from torchpaml._simulate.step_control import MAX_SUBSTEPS, simulate_to_tolerance
from torchpaml._simulate.stiffness import STIFF_SUBSTEPS, stable_substeps, stiffness
from torchpaml._simulate.warm import WarmStart

__all__ = ["checked_output", "simulate"]


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
        physics: an :class:`~torchpaml._physics.AbstractPhysics`.
        t: sample times in s, shape (time,), shared by the batch.
        u: input samples, shape (batch, time, n_input), float64.
        x0: initial state (batch, n_state), or of the base's states only (``physics + effect``: the effects' own
            states then start at their declared values, :func:`~torchpaml._physics.complete_state`); rest if omitted.
        solver: how to integrate (:mod:`~torchpaml._simulate.solvers`): :class:`~torchpaml.Auto` (the default:
            exact for linear physics on a uniform grid, else RK4 to ``rtol``, else, for stiff physics, TR-BDF2),
            :class:`~torchpaml.Exact`, :class:`~torchpaml.RK4`, :class:`~torchpaml.TRBDF2` or
            :class:`~torchpaml.Dopri5`. A fixed-step solver with ``substeps="auto"`` doubles its substeps until
            halving the step moves the output by at most ``rtol`` of its size
            (:func:`~torchpaml._simulate.step_control.simulate_to_tolerance`), and raises
            :class:`~torchpaml._errors.ResolutionError` when that takes more than 64. Calling the model,
            ``physics(t, u)``, simulates with its own ``physics.solver`` (the one its fit resolved).
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
        raise TypeError(f"simulate's fourth argument is the initial state; pass the solver by name: solver={x0!r}")
    solver = Auto() if solver is None else solver
    if not isinstance(solver, Solver):
        raise TypeError(f"solver must be one of torchpaml's solvers (Auto(), Exact(), RK4(), TRBDF2(), Dopri5()), "
                        f"got {solver!r}")
    x0 = complete_state(physics, x0, u.shape[0]).to(u)
    if check_hold(hold) == "zoh" and isinstance(solver, Dopri5):
        raise ValueError("hold='zoh' is simulated by the exact path and by the fixed-step solvers, not by Dopri5, "
                         "whose interpolant is first-order; use solver=RK4() or the default")
    if isinstance(solver, Exact):
        if physics.state_space() is None:
            raise ValueError(f"solver=Exact() needs linear physics; {type(physics).__name__} is nonlinear. Use RK4()")
        h = uniform_step(t)  # raises, naming the spacing, on a non-uniform grid
    else:
        h = exact_step(physics, t) if isinstance(solver, Auto) else None
    if h is not None:
        return checked_output(simulate_lti(*physics.state_space(), h, u, x0, hold), t, blowup)
    if isinstance(solver, Dopri5):
        states = simulate_ode(physics, t, u, x0, method="dopri5", rtol=solver.rtol, atol=solver.atol,
                              adjoint=solver.adjoint, max_num_steps=solver.max_num_steps, knots=knots)
        return checked_output(physics.output(states, u), t, blowup)
    if isinstance(solver, FixedStep):
        return _fixed_step(physics, t, u, x0, solver, warm, hold, blowup)
    try:
        return _fixed_step(physics, t, u, x0, RK4(rtol=solver.rtol), warm, hold, blowup, STIFF_SUBSTEPS)
    except (ResolutionError, SimulationError) as explicit:  # too stiff for RK4's step: the implicit method
        try:
            return _fixed_step(physics, t, u, x0, TRBDF2(rtol=solver.rtol), WarmStart(), hold, blowup)
        except (ResolutionError, SimulationError):
            raise explicit from None


def _fixed_step(physics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, solver: FixedStep,
                warm: WarmStart | None, hold: str, blowup: float, most_stable: int = MAX_SUBSTEPS) -> torch.Tensor:
    """The output by ``solver`` at its substeps, or to its ``rtol`` (``substeps="auto"``): step doubling from the
    model's own substeps where the model's solver is the same method.

    The step's stability (:mod:`~torchpaml._simulate.stiffness`; beyond ``most_stable`` substeps it raises
    :class:`~torchpaml._errors.ResolutionError`) is judged on a first trajectory, before the step doubling climbs
    (the linear base's exact one where there is one, which also sets where the doubling starts; else the first
    simulated), and on the accepted one (an unstable step can leave a stiff region that the first trajectory
    entered only briefly); a fixed step, on its own trajectory."""
    def judged(states: torch.Tensor) -> int:
        return stable_substeps(solver.at(1), stiffness(physics, t, u, states.detach()), most_stable)

    if solver.substeps != "auto":
        states = simulate_shooting(physics, t, u, x0, solver, warm, hold=hold)
        judged(states)  # refuses physics too stiff for the method
        return checked_output(physics.output(states, u), t, blowup)
    warm = WarmStart() if warm is None else warm  # the accepted step's solve starts the differentiable one
    own = physics.solver
    start = own.substeps if type(own) is type(solver) and own.substeps != "auto" else 1
    with torch.no_grad():
        guess = base_guess(physics, t, u, x0.detach(), hold)  # the linear base's exact trajectory, where there is one
    if guess is not None:
        start = max(start, judged(guess))
    trajectories: dict[int, torch.Tensor] = {}

    def run(m: int) -> torch.Tensor:
        states = simulate_shooting(physics, t, u, x0, solver.at(m), warm, hold=hold)
        if not trajectories and guess is None:
            judged(states)
        trajectories.clear()
        trajectories[m] = states.detach()
        return checked_output(physics.output(states, u), t, blowup)

    step = float((t[-1] - t[0]) / max(len(t) - 1, 1))
    while True:
        y, m = simulate_to_tolerance(run, start, solver.rtol, step, solver.order, type(solver).__name__)
        stable = judged(trajectories[m])
        if stable <= m:
            return y
        start = stable


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
