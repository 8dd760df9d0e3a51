"""Simulation of nonlinear physics with torchdiffeq solvers."""

from __future__ import annotations

import torch
from torch import nn
from torch.nn.utils import parametrize
from torchdiffeq import odeint, odeint_adjoint

from torchpaml._simulate.dynamics import Dynamics
from torchpaml._errors import SimulationError
from torchpaml._simulate.interpolation import LinearInterpolant

__all__ = ["simulate_ode", "ADAPTIVE_METHODS"]

ADAPTIVE_METHODS = ("dopri5", "dopri8", "bosh3", "fehlberg2", "adaptive_heun")


class _Vectorfield(nn.Module):
    """$(t, x) \\mapsto f(t, x, u(t))$ for torchdiffeq; a module so the adjoint finds the parameters."""

    def __init__(self, physics: nn.Module, interpolant: LinearInterpolant):
        super().__init__()
        self.physics, self.interpolant = physics, interpolant

    def forward(self, t, x):
        return self.physics.derivative(t, x, self.interpolant(t))


def simulate_ode(
    physics: Dynamics,
    t: torch.Tensor,
    u: torch.Tensor,
    x0: torch.Tensor,
    *,
    method: str = "dopri5",
    rtol: float = 1e-7,
    atol: float = 1e-9,
    adjoint: bool = False,
    max_num_steps: int = 1_000_000,
    knots: torch.Tensor | None = None,
) -> torch.Tensor:
    """Integrate the physics from ``x0`` over ``t`` with input ``u``; returns the state, (batch, time, n_state).

    ``knots`` are the times where the input's slope jumps (0.8 s apart for the paper's pseudorandom
    input; every sample time for arbitrary sampled data: pass ``knots=t``). Adaptive solvers are told
    to step on them (torchdiffeq's ``step_t``), so no step straddles a kink. Without knots, the
    solver's error control alone handles the small kinks of a finely sampled smooth input.
    """
    field = _Vectorfield(physics, LinearInterpolant(t, u))
    options = {}
    if method in ADAPTIVE_METHODS:
        options["max_num_steps"] = max_num_steps
        if knots is not None:
            options["step_t"] = knots.to(t)
    solve = odeint_adjoint if adjoint else odeint
    kwargs = {"adjoint_params": tuple(physics.parameters())} if adjoint else {}
    try:
        with parametrize.cached():
                states = solve(field, x0, t, method=method, rtol=rtol, atol=atol, options=options, **kwargs)
    except AssertionError as err:  # torchdiffeq signals step-size underflow and step limits this way
        raise SimulationError(
            f"the ODE solver ({method}) could not advance: {err}. The solution probably blows up or is very "
            "stiff for these parameters; check that the parameters are physical (e.g. positive damping) and "
            "that the input is scaled as the physics expects"
        ) from err
    return states.transpose(0, 1)
