r"""Stage 2 as a Lightning system: the residual fitted to $y - \hat y$ with the physics frozen."""

from __future__ import annotations

import copy
from typing import Literal

import torch
from torch import nn

from torchpaml._data import Record
from torchpaml._errors import DataError
from torchpaml._fit import fit_physics, reestimate_shift
from torchpaml._metrics import mismatch
from torchpaml._physics.base import AbstractPhysics
from torchpaml._residual.chebyshev_hammerstein import ChebyshevHammerstein
from torchpaml._training.system import HybridSystem
from torchpaml._simulate.solvers import Solver

__all__ = ["ResidualFit", "default_optimizer"]


def default_optimizer(residual: nn.Module, optimizer: str | None, lr: float | None) -> tuple[str, float]:
    """L-BFGS (lr 1) for the Chebyshev residual's few pole parameters, Adam (lr 3e-3) for networks."""
    chosen = optimizer or ("lbfgs" if isinstance(residual, ChebyshevHammerstein) else "adam")
    return chosen, lr if lr is not None else (1.0 if chosen == "lbfgs" else 3e-3)


class ResidualFit(HybridSystem):
    r"""Fit ``residual`` on the training records to $y - \hat y$, the physics frozen at its stage-1 estimate.

    The physics comes from ``physics_checkpoint`` (a :class:`PhysicsFit` checkpoint) or, without
    one, is fitted at the start of the run on the data module's ``identification`` records by
    :func:`~torchpaml.fit_physics`, the one physics fit. Its learnable
    parameters are the ones identified; after stage 1 they are frozen.

    The Chebyshev-Hammerstein residual is fitted by variable projection (L-BFGS over its poles,
    numerators by least squares at every evaluation); other residuals by ``optimizer`` over all
    their parameters. At the end of training the system logs the certificates of the fitted
    residual on the witness input and the first-order check $\Delta\theta$: $\theta$ re-estimated on
    the identification record minus the residual's output there.

    Args:
        physics: the physics, with the identified parameters marked learnable.
        residual: an output residual (``ChebyshevHammerstein``, ``MLPResidual``) or an ``MLPForce``
            (the MLP inside the ODE).
        physics_checkpoint: path of a stage-1 checkpoint.
        bounds: ``{name: [lower, upper]}`` for the identified parameters (see :class:`PhysicsFit`).
        optimizer: default L-BFGS for the Chebyshev residual, Adam otherwise.
        lr: learning rate; default 1 for L-BFGS, 3e-3 for Adam.
    """

    stage = "residual"

    def __init__(
        self,
        physics: AbstractPhysics,
        residual: nn.Module,
        physics_checkpoint: str | None = None,
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
        self.bounds = {name: tuple(b) for name, b in (bounds or {}).items()}
        self.attach(physics, residual, self.bounds)
        self.physics_checkpoint = physics_checkpoint
        physics.requires_grad_(False)
        self.register_buffer("physics_ready", torch.tensor(False))

    def trainable(self) -> list[nn.Parameter]:
        if self.uses_projection:
            return self.residual.pole_parameters()
        return [p for p in self.residual.parameters() if p.requires_grad]

    # -- stage 1 at the start of the run -------------------------------------------------------
    def _stage1_options(self) -> dict:
        return {"bounds": {name: self.bounds[name] for name in self.identified_names if name in self.bounds}}

    def _identification(self) -> dict | None:
        return self.trainer.datamodule.full_batch("identification")

    def on_fit_start(self) -> None:
        if bool(self.physics_ready):
            return  # resumed from a checkpoint of this run: the physics is in the state dict
        if self.physics_checkpoint is not None:
            checkpoint = torch.load(self.physics_checkpoint, map_location="cpu", weights_only=False)
            if "physical_parameters" not in checkpoint:
                raise DataError(
                    f"{self.physics_checkpoint} has no 'physical_parameters'; pass a checkpoint written by PhysicsFit"
                )
            self.physics.assign(**checkpoint["physical_parameters"])
        else:
            batch = self._identification()
            if batch is None:
                raise DataError(
                    "ResidualFit needs the physics: give it physics_checkpoint (a PhysicsFit checkpoint) or give "
                    "the data module identification records to fit the physics on"
                )
            self.physics.set_learnable(*self.identified_names)
            fit = fit_physics(self.physics, Record.records(batch["t"], batch["u"], batch["y"]), **self._stage1_options())
            self.physics_solver = fit.solver
            self.physics.requires_grad_(False)
            if self.logger is not None and self.trainer.is_global_zero:
                metrics = {f"physics/identification/{k}": v for k, v in fit.parameters.items()}
                metrics["physics/identification/mismatch_pct"] = 100 * fit.mismatch
                self.logger.log_metrics(metrics, step=0)
        self.physics_ready.fill_(True)

    # -- the first-order check ------------------------------------------------------------------
    def final_scalars(self) -> dict[str, float]:
        scalars = super().final_scalars()
        batch = self._identification()
        if batch is None or not self.identified_names:
            return scalars
        t, u, y = batch["t"], batch["u"], batch["y"]
        with torch.no_grad():
            y_physics, y_model = self.outputs(t, u)
        refit = copy.deepcopy(self.physics).set_learnable(*self.identified_names)
        shift = reestimate_shift(refit, y_model - y_physics, t, u, y, **self._stage1_options())
        scalars.update({f"{self.stage}/identification/delta_{k}": v for k, v in shift.items()})
        scalars[f"{self.stage}/identification/physics_mismatch_pct"] = 100 * mismatch(y, y_physics)
        if self.uses_projection:
            verdict = self.adequacy()
            scalars[f"{self.stage}/train/inadequate"] = float(verdict.inadequate)
            experiment = getattr(self.logger, "experiment", None)
            if hasattr(experiment, "add_text"):
                experiment.add_text(f"{self.stage}/verdict", verdict.message, global_step=self.global_step)
        return scalars

    def adequacy(self):
        """The inadequacy alarm (:func:`~torchpaml.assess_adequacy`) on the whole training and
        validation records: physics alone against physics + the orthogonal residual."""
        from torchpaml._diagnostics.analysis.adequacy import assess_adequacy

        data = self.trainer.datamodule
        mismatches = {split: self.record_mismatches(data.records(split)) for split in ("train", "validation")
                      if data.records(split)}
        validation = mismatches.get("validation", (None, None))
        return assess_adequacy(*mismatches["train"], *validation)
