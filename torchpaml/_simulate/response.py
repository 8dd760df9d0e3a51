r"""What an extra rate does to the output: the tangent-linear response along a physics' own trajectory.

For physics $\dot x = f(t, x, u)$, $y = h(x, u)$ and a small extra rate $w(t)$ on its state
equations, $\dot x = f(t, x, u) + w$, the output changes to first order by

$$ \delta y = \mathcal L[w], \qquad \dot{\delta x} = \partial_x f(t, x^0, u)\,\delta x + w, \quad
   \delta y = \partial_x h(x^0, u)\,\delta x, \quad \delta x(t_0) = 0, $$

linear in $w$, along the physics' trajectory $x^0$ on the record. :func:`forced_response` computes
$\mathcal L$ for many $w$ at once (one batch row each), by the one simulator:

* linear physics on a uniform grid: the exact path, with $w$ as further inputs (exact, since
  $\mathcal L$ is then the system's own response to them, from rest);
* otherwise: a central difference of two RK4 simulations with $\pm\varepsilon w$, warm-started from
  the physics' trajectory (error $O(\varepsilon^2)$; $\varepsilon$ makes $\varepsilon w$ a
  :data:`PROBE` share of the rates along the trajectory).
"""

from __future__ import annotations

import torch
from torch import nn

from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.solvers import Auto, Solver
from torchpaml._simulate.simulator import simulate
from torchpaml._simulate.warm import WarmStart

__all__ = ["forced_response"]

#: Size of a probe rate, as a share of the physics' own rates along its trajectory (RMS).
PROBE = 1e-4
#: Rows per simulation (bounds the memory of long records).
ROW_SAMPLES = 4_000_000


class _Injected(nn.Module):
    """``physics`` with one more input channel per state, added to that state's rate (a :class:`Dynamics`)."""

    def __init__(self, physics: Dynamics):
        super().__init__()
        self.physics = physics
        self.state_names, self.output_dim, self.state_dim = physics.state_names, physics.output_dim, physics.state_dim
        self.input_dim = physics.input_dim + physics.state_dim
        self.display_name = f"{physics.display_name} with injected rates"

    def derivative(self, t, x, u):
        m = self.physics.input_dim
        return self.physics.derivative(t, x, u[..., :m]) + u[..., m:]

    def output(self, x, u):
        return self.physics.output(x, u[..., : self.physics.input_dim])

    def initial_state(self, batch):
        return self.physics.initial_state(batch)

    def linear_base(self):
        return None

    def state_space(self):
        matrices = self.physics.state_space()
        if matrices is None:
            return None
        A, B, C, D = matrices
        n = A.shape[0]
        return (A, torch.cat([B, torch.eye(n, dtype=B.dtype)], dim=1), C,
                torch.cat([D, torch.zeros(D.shape[0], n, dtype=D.dtype)], dim=1))


def forced_response(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor,
                    rates: torch.Tensor, hold: str = "foh", solver: Solver | None = None) -> torch.Tensor:
    r"""$\mathcal L[w]$ (module docstring) for each of ``rates``, without gradients.

    Args:
        physics: the physics, at its fitted parameters.
        t: (time,) from 0; u: (1, time, n_input); x0: (1, n_state): one record.
        rates: $w$, (k, time, n_state): k extra rates on the state equations.
        hold: how the input (and the rates) move between samples.
        solver: the solver ``physics`` was fitted with, at whose resolution it is simulated (``Auto(start=solver)``).

    Returns:
        (k, time, n_output).
    """
    injected = _Injected(physics)
    n = physics.state_dim
    chunk = max(1, ROW_SAMPLES // (2 * len(t) * max(n, 1)))
    linear = physics.state_space() is not None
    parts = []
    with torch.no_grad():
        if linear:
            drive = torch.zeros(1, len(t), u.shape[-1], dtype=u.dtype)
            rest = torch.zeros(1, n, dtype=u.dtype)
            for rows in rates.split(chunk):
                inputs = torch.cat([drive.expand(len(rows), -1, -1), rows], dim=-1)
                parts.append(simulate(injected, t, inputs, rest.expand(len(rows), -1), hold=hold))
            return torch.cat(parts)
        engine = Auto(start=solver)
        base = engine.states(physics, t, u, x0, hold=hold)
        speed = physics.derivative(t, base[0], u[0]).square().mean(dim=0).sqrt()  # each rate's RMS (n,)
        for rows in rates.split(chunk):
            size = rows.square().mean(dim=1).sqrt()  # (rows, n)
            eps = PROBE * float((speed / size.clamp_min(1e-300)).min().clamp(max=1e300))
            signed = torch.cat([eps * rows, -eps * rows])
            inputs = torch.cat([u.expand(len(signed), -1, -1), signed], dim=-1)
            starts = x0.expand(len(signed), -1)
            states = engine.states(injected, t, inputs, starts, warm=WarmStart(base.expand(len(signed), -1, -1)),
                                   hold=hold)
            y = injected.output(states, inputs)
            parts.append((y[: len(rows)] - y[len(rows):]) / (2 * eps))
    return torch.cat(parts)
