r"""What the three training systems share: the loss, the metrics, the optimiser, the figures, the certificates.

Scalars are named ``stage/split/metric``: ``stage`` is ``physics``, ``residual`` or ``joint``;
``split`` is ``train``, ``validation``, ``test``, ``identification`` (the physics-identification record)
or ``witness`` ($\alpha\cos\omega t$, where the certificates are measured); metrics are
``mismatch_pct`` and ``fit_pct`` (of the stage's model: the hybrid in stages 2 and joint),
``physics_mismatch_pct`` (the physics alone, for comparison), the physical parameters by name,
``delta_<θ>`` (the first-order check) and ``certificate_zeroth``/``certificate_first_<θ>``.

The loss of a batch is the squared mismatch over the scored samples (after the washout),

$$ L = \frac{\sum_{b,t \ge t_w} (y - \hat y)^2}{\sum_{b,t \ge t_w} y^2}; $$

under DDP both sums run over every process's share of the batch (:meth:`HybridSystem.global_loss`),
so all ranks see the same loss and gradient, and L-BFGS line searches stay in step.
"""

from __future__ import annotations

import lightning as L
import torch
from torch import nn

from torchpaml._errors import ConfigurationError
from torchpaml._certificates import incompatibility_certificates
from torchpaml._fit.residual_fit import project
from torchpaml._metrics import fit_percent, mismatch
from torchpaml._render.figures import overlay_figure, residual_figure, spectrum_figure
from torchpaml._signals import dominant_frequency
from torchpaml._residual.chebyshev_hammerstein import ChebyshevHammerstein
from torchpaml._residual.hybrid import Hybrid
from torchpaml._simulate.simulator import simulate
from torchpaml._simulate.solvers import Solver
from torchpaml._simulate.warm import WarmStart

__all__ = ["HybridSystem"]


def scored(batch: dict, signal: torch.Tensor) -> torch.Tensor:
    """The samples of ``signal`` (batch, time, ch) that count: those after the washout."""
    return signal[:, batch["washout"] :]


class HybridSystem(L.LightningModule):
    r"""Abstract base of :class:`PhysicsFit`, :class:`ResidualFit` and :class:`JointFit`.

    Subclasses set ``stage``, ``self.physics`` and ``self.residual`` (``None`` in stage 1) and
    :meth:`trainable` (the parameters handed to the optimiser).

    Args (shared by the subclasses):
        optimizer: ``"lbfgs"`` (``torch.optim.LBFGS``, ``max_iter`` inner iterations per step,
            strong-Wolfe line search; for a handful of smooth parameters) or ``"adam"`` (networks).
        lr: learning rate (L-BFGS: the initial step, 1 is the natural choice).
        lr_decay: Adam's learning rate is multiplied by this factor after every epoch
            (``torch.optim.lr_scheduler.ExponentialLR``; 1 keeps it constant). A decay lets Adam settle
            instead of spiking late in training; being per epoch, it resumes exactly from a checkpoint.
        solver: the solver of a learned force's model (the physics inside the ODE with an :class:`MLPForce`,
            :mod:`~torchpaml._simulate.solvers`); default the one stage 1 resolved (:attr:`physics_solver`), with
            which the physics alone always simulates.
        witness_amplitude: $\alpha$ of the certificates' witness input $\alpha\cos\omega t$; default the
            Chebyshev residual's $\alpha$, else max|u| of the training data.
        witness_omega: $\omega$ of the witness input, rad/s.
        witness_duration: length of the witness input, s.
    """

    stage = ""

    def __init__(
        self,
        *,
        optimizer: str,
        lr: float,
        max_iter: int,
        solver: Solver | None,
        lr_decay: float,
        witness_amplitude: float | None,
        witness_omega: float,
        witness_duration: float,
    ):
        super().__init__()
        if optimizer not in ("lbfgs", "adam"):
            raise ConfigurationError(f"optimizer must be 'lbfgs' or 'adam', got {optimizer!r}")
        if not 0 < lr_decay <= 1:
            raise ConfigurationError(f"lr_decay must lie in (0, 1], got {lr_decay}")
        self.optimizer_name, self.lr, self.max_iter, self.lr_decay = optimizer, float(lr), int(max_iter), lr_decay
        self.solver = solver
        #: The solver stage 1's fit resolved (``PhysicsEstimate.solver``); ``None`` (``Auto()``) before it.
        self.physics_solver: Solver | None = None
        self.witness = (witness_amplitude, float(witness_omega), float(witness_duration))
        self.physics: nn.Module
        self.residual: nn.Module | None = None
        self._warm: dict[tuple[str, int], WarmStart] = {}

    # -- the model ---------------------------------------------------------------------------
    def attach(self, physics: nn.Module, residual: nn.Module | None, bounds: dict | None) -> None:
        """Install the model: bound the named parameters, record the identified ones, and take the
        Chebyshev numerators out of the optimiser (variable projection sets them)."""
        if residual is not None:
            Hybrid(physics, residual)  # validates the pairing
        for name, (lower, upper) in (bounds or {}).items():
            physics.bound(name, lower, upper)
        self.physics, self.residual = physics, residual
        self._identified = physics.learnable_names()
        if self.uses_projection:
            residual.numerator.requires_grad_(False)
            residual.direct.requires_grad_(False)

    @property
    def identified_names(self) -> list[str]:
        """The physical parameters this workflow identifies (learned in stage 1 or jointly)."""
        return list(self._identified)

    def outputs(self, t: torch.Tensor, u: torch.Tensor, warm: WarmStart | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """``(y_physics, y_model)``: the physics alone and the stage's model (the same in stage 1).

        ``warm``: a nonlinear model's Newton warm start (:func:`~torchpaml.simulate`), see :meth:`warm_start`.
        """
        if self.residual is None:
            y = simulate(self.physics, t, u, warm=warm, solver=self.physics_solver)
            return y, y
        return Hybrid(self.physics, self.residual)(t, u, warm=warm, solver=self.solver,
                                                   physics_solver=self.physics_solver)

    def warm_start(self, split: str, batch_idx: int) -> WarmStart:
        """The warm start of one batch of ``split``: every epoch simulates the same batches (the loaders do not
        shuffle) under parameters that moved little, so each RK4 solve starts from the last one's states."""
        return self._warm.setdefault((split, batch_idx), WarmStart())

    def trainable(self) -> list[nn.Parameter]:
        raise NotImplementedError

    @property
    def uses_projection(self) -> bool:
        """Whether the Chebyshev numerators are eliminated by variable projection (not optimised)."""
        return isinstance(self.residual, ChebyshevHammerstein)

    def projected_outputs(self, batch: dict) -> tuple[torch.Tensor, torch.Tensor]:
        r"""Scored ``(y_physics, y_model)`` with the Chebyshev coefficients at their least-squares optimum.

        $\hat y + \Psi(\rho)\,c(\rho)$ with $c$ the ridge least-squares fit of $y - \hat y$ on the scored
        samples (:func:`~torchpaml._fit.residual_fit.project`); sets the residual's coefficients to $c$.
        """
        t, u, y = batch["t"], batch["u"], batch["y"]
        y_physics = simulate(self.physics, t, u, solver=self.physics_solver)
        regressors = scored(batch, self.residual.regressors(t, u))
        coefficients, fitted = project(regressors, scored(batch, y - y_physics)[..., 0])
        self.residual.set_coefficients(coefficients.detach())
        y_physics = scored(batch, y_physics)
        return y_physics, y_physics + fitted[..., None]

    # -- training ----------------------------------------------------------------------------
    def setup(self, stage: str) -> None:
        if self.trainer.world_size > 1 and self.uses_projection:
            raise ConfigurationError(
                "the Chebyshev residual's variable projection solves one least-squares problem over all records "
                "and does not run across processes; train it with devices: 1 (it is fast), or use DDP for "
                "stage 1 and for the MLP baselines"
            )

    def training_step(self, batch: dict, batch_idx: int) -> torch.Tensor:
        y = scored(batch, batch["y"])
        if self.uses_projection:
            y_physics, y_model = self.projected_outputs(batch)
        else:
            y_physics, y_model = (scored(batch, s)
                                  for s in self.outputs(batch["t"], batch["u"], self.warm_start("train", batch_idx)))
        loss = self.global_loss(torch.sum((y - y_model) ** 2), torch.sum(y**2))
        values = {"loss": loss.detach(), "mismatch_pct": 100 * mismatch(y, y_model)}
        if self.residual is not None:
            values["physics_mismatch_pct"] = 100 * mismatch(y, y_physics)
        values.update(self.physics.physical_parameters())
        self.log_dict({f"{self.stage}/train/{k}": float(v) for k, v in values.items()}, batch_size=len(y))
        return loss

    def global_loss(self, error: torch.Tensor, energy: torch.Tensor) -> torch.Tensor:
        r"""error / energy over every process's records (module docstring), differentiable in this rank's error.

        With $W$ processes: the value is $\sum_r e_r / \sum_r E_r$ on every rank, the gradient
        $W\,\partial e_{\text{own}} / \sum_r E_r$, which DDP's gradient averaging turns into the
        gradient of the global loss.
        """
        world = self.trainer.world_size
        if world == 1:
            return error / energy
        totals = self.trainer.strategy.reduce(torch.stack([error.detach(), energy.detach()]), reduce_op="sum")
        local = world * error / totals[1]
        return local + (totals[0] / totals[1] - local).detach()

    def on_train_batch_end(self, outputs, batch: dict, batch_idx: int) -> None:
        if self.uses_projection:  # the coefficients that go with the poles the optimiser ended on
            with torch.no_grad():
                self.projected_outputs(batch)

    def configure_optimizers(self):
        params = self.trainable()
        if self.optimizer_name == "lbfgs":
            return torch.optim.LBFGS(
                params, lr=self.lr, max_iter=self.max_iter, line_search_fn="strong_wolfe",
                tolerance_grad=1e-12, tolerance_change=1e-14,
            )
        adam = torch.optim.Adam(params, lr=self.lr)
        return {"optimizer": adam, "lr_scheduler": torch.optim.lr_scheduler.ExponentialLR(adam, self.lr_decay)}

    # -- evaluation --------------------------------------------------------------------------
    def evaluate(self, batch: dict, split: str, batch_idx: int) -> dict[str, float]:
        """Log and return the metrics of the stage's model on ``batch``."""
        with torch.no_grad():
            y_physics, y_model = (scored(batch, s)
                                  for s in self.outputs(batch["t"], batch["u"], self.warm_start(split, batch_idx)))
        y = scored(batch, batch["y"])
        values = {"mismatch_pct": 100 * mismatch(y, y_model), "fit_pct": fit_percent(y, y_model)}
        if self.residual is not None:
            values["physics_mismatch_pct"] = 100 * mismatch(y, y_physics)
        self.log_dict({f"{self.stage}/{split}/{k}": v for k, v in values.items()}, batch_size=len(y))
        return values

    def validation_step(self, batch: dict, batch_idx: int) -> None:
        self.evaluate(batch, "validation", batch_idx)

    def test_step(self, batch: dict, batch_idx: int) -> None:
        self.evaluate(batch, "test", batch_idx)

    def record_mismatches(self, records: list) -> tuple[float, float]:
        r"""Mismatch (fraction) of the physics alone and of the stage's model over whole records.

        $\sqrt{\sum_i \|y_i - \hat y_i\|^2 / \sum_i \|y_i\|^2}$ over :class:`~torchpaml.Record`
        records, each simulated from rest in full.
        """
        errors, energy = [0.0, 0.0], 0.0
        with torch.no_grad():
            for record in records:
                t, u, y = record.batch()
                for i, y_hat in enumerate(self.outputs(t - t[0], u)):
                    errors[i] += float(torch.sum((y - y_hat) ** 2))
                energy += float(torch.sum(y**2))
        return (errors[0] / energy) ** 0.5, (errors[1] / energy) ** 0.5

    def record_mismatch(self, records: list) -> float:
        """Mismatch (fraction) of the stage's model over whole records (:meth:`record_mismatches`)."""
        return self.record_mismatches(records)[1]

    # -- reports: figures and certificates -----------------------------------------------------
    def on_train_end(self) -> None:
        self.report()

    def on_validation_end(self) -> None:
        if self.trainer.state.fn == "validate":
            self.report()

    def on_test_end(self) -> None:
        self.report()

    def report(self) -> None:
        """Figures and end-of-stage scalars, written to the logger by rank 0."""
        if self.trainer.sanity_checking or not self.trainer.is_global_zero or self.logger is None:
            return
        scalars = self.final_scalars()
        if scalars:
            self.logger.log_metrics(scalars, step=self.global_step)
        experiment = getattr(self.logger, "experiment", None)
        if hasattr(experiment, "add_figure"):
            for tag, figure in self.figures().items():
                experiment.add_figure(f"{self.stage}/{tag}", figure, global_step=self.global_step, close=True)
            experiment.flush()

    def final_scalars(self) -> dict[str, float]:
        """End-of-stage scalars (the certificates; stage 2 adds Δθ)."""
        if self.residual is None or not self.identified_names:
            return {}
        return self.certificates()

    def certificates(self) -> dict[str, float]:
        r"""$|c_0|$ and $|c_1|$ per identified parameter of the *fitted* residual on the witness input."""
        amplitude, omega, duration = self.witness
        if amplitude is None:
            amplitude = self.residual.alpha or self._training_amplitude()
        hybrid = Hybrid(self.physics, self.residual)

        def fitted_residual(generator):
            return lambda t, u, y: hybrid(t, u, solver=self.solver, physics_solver=self.physics_solver)[1] - y

        scalars = {}
        for name in self.identified_names:
            c = incompatibility_certificates(
                self.physics, fitted_residual, alpha=amplitude, parameter=name, omega=omega, duration=duration, draws=1,
                solver=self.physics_solver)
            scalars[f"{self.stage}/witness/certificate_zeroth"] = c.zeroth[0]
            scalars[f"{self.stage}/witness/certificate_first_{name}"] = c.first[0]
        return scalars

    def _training_amplitude(self) -> float:
        return float(self.trainer.datamodule.full_batch("train")["u"].abs().max())

    def figures(self) -> dict:
        """Overlay and residual on the validation data (else training), spectrum on the identification record."""
        datamodule = self.trainer.datamodule
        batch = datamodule.full_batch("validation") or datamodule.full_batch("train")
        periodic = datamodule.full_batch("identification") or batch
        figures = {}
        with torch.no_grad():
            t, u, y = batch["t"], batch["u"][:1], batch["y"][:1]
            y_physics, y_model = self.outputs(t, u)
            models = {"physics": y_physics} if self.residual is None else {"physics": y_physics, "hybrid": y_model}
            figures["validation/overlay"] = overlay_figure(t, y, models, f"{self.stage}: {batch['names'][0]}")
            if self.residual is not None:
                figures["validation/residual"] = residual_figure(t, y - y_physics, y_model - y_physics)
            t, u, y = periodic["t"], periodic["u"][:1], periodic["y"][:1]
            y_physics, _ = self.outputs(t, u)
            figures["identification/spectrum"] = spectrum_figure(
                t, y - y_physics, dominant_frequency(t, u), title=f"spectrum of y − ŷ: {periodic['names'][0]}"
            )
        return figures

    def on_save_checkpoint(self, checkpoint: dict) -> None:
        checkpoint["physical_parameters"] = self.physics.physical_parameters()
