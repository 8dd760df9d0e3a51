"""Stage 1 as a Lightning system: the physical parameters by the output-error (prediction error) method."""

from __future__ import annotations

from torch import nn

from torchpaml.physics.base import AbstractPhysics
from torchpaml.training.system import HybridSystem

__all__ = ["PhysicsFit"]


class PhysicsFit(HybridSystem):
    r"""Fit the learnable parameters of ``physics`` to the training records: $\min_\theta \|y - \mathcal H^\theta[u]\|^2$.

    Args:
        physics: the physics, with the parameters to identify marked learnable.
        bounds: ``{name: [lower, upper]}``, open intervals the named parameters are kept in
            (:meth:`~torchpaml.physics.AbstractPhysics.bound`), e.g. the paper's ζ in (0.001, 5).
        optimizer, lr, max_iter, simulation: see :class:`~torchpaml.training.system.HybridSystem`.

    The checkpoint carries ``physical_parameters`` (values in physical units), which
    :class:`ResidualFit` reads with ``physics_checkpoint``.
    """

    stage = "physics"

    def __init__(
        self,
        physics: AbstractPhysics,
        bounds: dict[str, tuple[float, float]] | None = None,
        optimizer: str = "lbfgs",
        lr: float = 1.0,
        max_iter: int = 20,
        lr_decay: float = 1.0,
        simulation: dict | None = None,
    ):
        super().__init__(
            optimizer=optimizer, lr=lr, max_iter=max_iter, simulation=simulation, lr_decay=lr_decay,
            witness_amplitude=None, witness_omega=1.0, witness_duration=80.0,
        )
        self.save_hyperparameters(ignore=["physics"])
        self.attach(physics, None, bounds)
        if not self._identified:
            raise ValueError(f"{physics.display_name} has no learnable parameter; list the ones to fit in learn=[...]")

    def trainable(self) -> list[nn.Parameter]:
        return [p for p in self.physics.parameters() if p.requires_grad]
