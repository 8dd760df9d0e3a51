"""The baseline the two-stage fit is contrasted with: physics and residual trained together."""

from __future__ import annotations

from typing import Literal

from torch import nn

from torchpaml._physics.base import AbstractPhysics
from torchpaml._training.residual_fit import default_optimizer
from torchpaml._training.system import HybridSystem
from torchpaml._simulate.solvers import Solver

__all__ = ["JointFit"]


class JointFit(HybridSystem):
    r"""Train the learnable physical parameters and the residual together.

    $\min_{\theta,\gamma} \|y - \mathcal H^\theta[u] - \mathcal R^\gamma[u]\|^2$.

    With the Chebyshev-Hammerstein residual the numerators are eliminated by variable projection
    and L-BFGS runs over $\theta$ and the poles; first-order incompatibility then keeps $\hat\theta$
    at the physics-only estimate. With an MLP, Adam trains everything, and $\hat\theta$ is no longer
    identifiable: the network absorbs whatever the physics does not explain.

    Args: as :class:`ResidualFit`, without the physics checkpoint (the physics starts from its
    initial values and is trained).
    """

    stage = "joint"

    def __init__(
        self,
        physics: AbstractPhysics,
        residual: nn.Module,
        bounds: dict[str, tuple[float, float]] | None = None,
        optimizer: Literal["lbfgs", "adam"] | None = None,
        lr: float | None = None,
        max_iter: int = 20,
        lr_decay: float = 1.0,
        solver: Solver | None = None,
        witness_amplitude: float | None = None,
        witness_omega: float = 1.0,
        witness_duration: float = 80.0,
    ):
        optimizer, lr = default_optimizer(residual, optimizer, lr)
        super().__init__(
            optimizer=optimizer, lr=lr, max_iter=max_iter, solver=solver, lr_decay=lr_decay,
            witness_amplitude=witness_amplitude, witness_omega=witness_omega, witness_duration=witness_duration,
        )
        self.save_hyperparameters(ignore=["physics", "residual"])
        self.attach(physics, residual, bounds)

    def trainable(self) -> list[nn.Parameter]:
        physics = [p for p in self.physics.parameters() if p.requires_grad]
        if self.uses_projection:
            return physics + self.residual.pole_parameters()
        return physics + [p for p in self.residual.parameters() if p.requires_grad]
