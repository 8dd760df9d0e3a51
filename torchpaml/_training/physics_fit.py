"""Stage 1 as a Lightning system: a thin wrapper that calls :func:`~torchpaml.fit_physics` on the training records."""

from __future__ import annotations

import torch
from torch import nn

from torchpaml._errors import ConfigurationError
from torchpaml._data import Record
from torchpaml._fit import fit_physics
from torchpaml._metrics import mismatch
from torchpaml._physics.base import AbstractPhysics
from torchpaml._training.system import HybridSystem, scored
from torchpaml._simulate.simulator import simulate
from torchpaml._simulate.solvers import Solver

__all__ = ["PhysicsFit"]


class PhysicsFit(HybridSystem):
    r"""Fit the learnable parameters of ``physics`` to the training records: $\min_\theta \|y - \mathcal H^\theta[u]\|^2$.

    Each training step runs :func:`~torchpaml.fit_physics` (trust region, the one physics fit)
    on the whole records of the batch, from the current parameters; under DDP the records of every
    process are gathered first, so every rank fits the same problem. A later epoch restarts the fit
    where the last one ended (it stops at once if that was the optimum).

    Args:
        physics: the physics, with the parameters to identify marked learnable.
        bounds: ``{name: [lower, upper]}``, open intervals the named parameters are kept in
            (:meth:`~torchpaml.AbstractPhysics.bound`), e.g. the paper's ζ in (0.001, 5).
        optimizer: unused (``fit_physics`` is the optimiser); accepted so that every system's config has the same keys.
        lr: unused, as ``optimizer``.
        lr_decay: unused, as ``optimizer``.
        solver: unused, as ``optimizer`` (``fit_physics`` resolves its own).
        max_iter: trust-region iterations of one training step.

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
        solver: Solver | None = None,
    ):
        super().__init__(
            optimizer=optimizer, lr=lr, max_iter=max_iter, solver=solver, lr_decay=lr_decay,
            witness_amplitude=None, witness_omega=1.0, witness_duration=80.0,
        )
        self.save_hyperparameters(ignore=["physics"])
        self.attach(physics, None, bounds)
        if not self._identified:
            raise ConfigurationError(f"{physics.display_name} has no learnable parameter; list the ones to fit in learn=[...]")

        self.automatic_optimization = False

    def trainable(self) -> list[nn.Parameter]:
        return [p for p in self.physics.parameters() if p.requires_grad]

    def training_step(self, batch: dict, batch_idx: int) -> None:
        u, y = batch["u"], batch["y"]
        if self.trainer.world_size > 1:
            u, y = (self.all_gather(v).flatten(0, 1) for v in (u, y))
        fit = fit_physics(self.physics, Record.records(batch["t"], u, y), max_nfev=self.max_iter)
        self.physics_solver = fit.solver
        with torch.no_grad():
            y_model = scored(batch, simulate(self.physics, batch["t"], u, solver=fit.solver))
        values = {"loss": fit.mismatch**2, "mismatch_pct": 100 * mismatch(scored(batch, y), y_model),
                  **self.physics.physical_parameters()}
        self.log_dict({f"{self.stage}/train/{k}": float(v) for k, v in values.items()}, batch_size=len(y))
