"""How a fixed-step solver (RK4, TR-BDF2) simulates: in the shooting engine at its substeps, or doubling them to its
``rtol`` (``substeps="auto"``), its step's stability checked either way."""

from __future__ import annotations

import torch

from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.method import Method
from torchpaml._simulate.blowup import checked_output
from torchpaml._simulate.shooting import base_guess, simulate_shooting
from torchpaml._simulate.step_control import MAX_SUBSTEPS, simulate_to_tolerance
from torchpaml._simulate.stiffness import stable_substeps, stiffness
from torchpaml._simulate.warm import WarmStart


__all__ = ["simulate_fixed_step"]


def simulate_fixed_step(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, solver: Method,
                        warm: WarmStart | None, hold: str, blowup: float, *, most_stable: int = MAX_SUBSTEPS,
                        start: int = 1) -> torch.Tensor:
    """The output (batch, time, n_output) by ``solver`` at its substeps, or to its ``rtol`` (``substeps="auto"``):
    step doubling from ``start`` substeps (a previous fit's, :attr:`~torchpaml.Auto.start`).

    The step's stability (:mod:`~torchpaml._simulate.stiffness`; beyond ``most_stable`` substeps it raises
    :class:`~torchpaml.ResolutionError`) is judged on a first trajectory, before the step doubling climbs
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
