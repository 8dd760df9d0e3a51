"""``torchpaml fit|validate|test --config FILE.yaml``: the systems and the data module through ``LightningCLI``.

The model is any :class:`~torchpaml.HybridSystem` (``class_path``: ``torchpaml.PhysicsFit``,
``ResidualFit`` or ``JointFit``), the data an :class:`~torchpaml.RecordDataModule`. Defaults
that differ from Lightning's: float64 (``precision: 64-true``), a scalar per step (``log_every_n_steps: 1``:
full-batch training takes one step per epoch), and a ``last.ckpt`` beside the best checkpoint, to
resume with ``--ckpt_path``. The resolved config is saved as ``config.yaml`` beside the TensorBoard logs.
"""

from __future__ import annotations

import sys

from lightning.pytorch.callbacks import ModelCheckpoint
from lightning.pytorch.cli import LightningCLI

from torchpaml._training.datamodule import RecordDataModule
from torchpaml._training.system import HybridSystem

__all__ = ["run_lightning", "trainer_defaults"]


def trainer_defaults() -> dict:
    """The Trainer settings that differ from Lightning's (module docstring); fresh callbacks for every run."""
    return {"precision": "64-true", "log_every_n_steps": 1, "callbacks": [ModelCheckpoint(save_last=True)]}


def run_lightning(args: list[str], prog: str = "torchpaml") -> LightningCLI:
    """Run ``LightningCLI`` on ``args`` (e.g. ``["fit", "--config", "run.yaml"]``); the process's own
    arguments are left for ``LightningCLI`` to read itself."""
    return LightningCLI(
        HybridSystem,
        RecordDataModule,
        subclass_mode_model=True,
        trainer_defaults=trainer_defaults(),
        save_config_kwargs={"overwrite": True},
        parser_kwargs={"prog": prog},
        args=None if args == sys.argv[1:] else args,
    )
