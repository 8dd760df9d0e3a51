r"""A physics model with a learned correction, in either of the two placements.

* output-additive (an :class:`~torchpaml.AbstractResidual`): $y = \mathcal H^\theta[u] + \mathcal R^\gamma[u, \hat y]$;
* a learned force inside the ODE (an :class:`~torchpaml.MLPForce`): $y$ is the output of
  :class:`~torchpaml.ForceAugmented` (physics + force), and the implied residual is
  $r = y - \mathcal H^\theta[u]$.
"""

from __future__ import annotations

import torch
from torch import nn

from torchpaml._errors import ConfigurationError
from torchpaml._residual.base import AbstractResidual
from torchpaml._residual.mlp import ForceAugmented, MLPForce
from torchpaml._simulate.warm import WarmStart
from torchpaml._simulate.simulator import simulate
from torchpaml._simulate.solvers import Solver

__all__ = ["Hybrid"]


class Hybrid(nn.Module):
    """``physics`` plus ``residual`` (an output residual or an :class:`MLPForce`).

    ``forward(t, u, warm=None, solver=None, physics_solver=None)`` returns ``(y_physics, y_hybrid)``, both (batch,
    time, n_y). The physics simulates with ``physics_solver`` (its fit's ``PhysicsEstimate.solver``; default
    ``Auto()``). ``warm`` and ``solver`` (see :func:`~torchpaml.simulate`; default ``physics_solver``) serve the
    hybrid's simulation with a learned force only, so that the two simulations of a nonlinear model do not
    overwrite each other's states.
    """

    def __init__(self, physics: nn.Module, residual: nn.Module):
        super().__init__()
        if not isinstance(residual, (AbstractResidual, MLPForce)):
            raise ConfigurationError(
                f"residual must be an output residual (AbstractResidual) or a learned force (MLPForce), got "
                f"{type(residual).__name__}"
            )
        self.physics, self.residual = physics, residual

    @property
    def in_ode(self) -> bool:
        """Whether the correction acts inside the ODE (a force) rather than on the output."""
        return isinstance(self.residual, MLPForce)

    def forward(self, t: torch.Tensor, u: torch.Tensor, warm: WarmStart | None = None, solver: Solver | None = None,
                physics_solver: Solver | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        y_physics = simulate(self.physics, t, u, solver=physics_solver)
        if self.in_ode:
            force = ForceAugmented(self.physics, self.residual)
            return y_physics, simulate(force, t, u, warm=warm, solver=physics_solver if solver is None else solver)
        return y_physics, y_physics + self.residual(t, u, y_physics)
