"""``torchpaml fit|validate|test`` end to end: every shipped config, TensorBoard contents, resume, DDP, errors."""

import subprocess
import sys
from pathlib import Path

import pytest
import torch
import yaml
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from torchpaml.cli.lightning import run_lightning

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = sorted((ROOT / "experiments").rglob("*.yaml"))
SPLITS = ("identification", "train", "validation", "test")


def short(config: Path, logs: Path, epochs: int = 2, duration: float = 20.0) -> list[str]:
    """Overrides for a few steps on short records, logged under ``logs``."""
    spec = yaml.safe_load(config.read_text())
    args = ["--config", str(config), f"--trainer.max_epochs={epochs}", "--trainer.check_val_every_n_epoch=1",
            "--trainer.enable_progress_bar=false", f"--trainer.logger.init_args.save_dir={logs}"]
    args += [f"--data.{split}.init_args.duration={duration}" for split in SPLITS if spec["data"].get(split)]
    if not spec["model"]["class_path"].endswith("PhysicsFit"):
        args.append(f"--model.init_args.witness_duration={duration}")
    return args


def run_dir(logs: Path) -> Path:
    (version,) = logs.glob("*/version_*")
    return version


def test_the_shipped_configs_are_found():
    names = {c.stem for c in CONFIGS}
    for alpha in (4, 10):
        assert {f"alpha{alpha}_{r}" for r in ("physics", "chebyshev", "mlp_output", "mlp_ode")} <= names
    assert {f"joint_alpha4_{r}" for r in ("chebyshev", "mlp_output", "mlp_ode")} <= names


@pytest.mark.slow
@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: c.stem)
def test_every_config_trains_end_to_end_on_short_records(config, tmp_path):
    cli = run_lightning(["fit", *short(config, tmp_path)])
    run = run_dir(tmp_path)
    assert (run / "config.yaml").exists() and (run / "checkpoints" / "last.ckpt").exists()
    checkpoint = torch.load(run / "checkpoints" / "last.ckpt", weights_only=False)
    assert checkpoint["physical_parameters"] == pytest.approx(cli.model.physics.physical_parameters(), rel=1e-12)
    assert cli.trainer.current_epoch == 2
    assert 0 < cli.model.record_mismatch(cli.datamodule.records("validation")) < 10


@pytest.fixture(scope="module")
def chebyshev_run(tmp_path_factory):
    logs = tmp_path_factory.mktemp("logs")
    config = ROOT / "experiments/paper/alpha4_chebyshev.yaml"
    cli = run_lightning(["fit", *short(config, logs, epochs=3, duration=40.0)])
    return cli, run_dir(logs)


@pytest.mark.slow
def test_tensorboard_holds_the_documented_scalars_and_figures(chebyshev_run):
    _, run = chebyshev_run
    events = EventAccumulator(str(run), size_guidance={"scalars": 0, "images": 0})
    events.Reload()
    scalars = {tag: [e.value for e in events.Scalars(tag)] for tag in events.Tags()["scalars"]}
    expected = [f"residual/{split}/{metric}" for split in ("train", "validation")
                for metric in ("mismatch_pct", "physics_mismatch_pct")]
    expected += ["residual/validation/fit_pct", "residual/train/zeta", "residual/train/omega0", "residual/train/gain",
                 "residual/identification/delta_zeta", "residual/witness/certificate_zeroth",
                 "residual/witness/certificate_first_zeta", "physics/identification/zeta",
                 "physics/identification/mismatch_pct"]
    assert set(expected) <= set(scalars)
    assert len(scalars["residual/train/mismatch_pct"]) == 3  # one per step
    assert scalars["residual/validation/mismatch_pct"][-1] < scalars["residual/validation/physics_mismatch_pct"][-1]
    assert scalars["residual/witness/certificate_zeroth"][0] < 1e-3  # the Chebyshev residual: orthogonal
    assert abs(scalars["residual/identification/delta_zeta"][0]) < 0.01
    assert scalars["residual/train/inadequate"] == [0.0]  # alpha = 4: the physics is adequate
    assert "residual/verdict/text_summary" in events.Tags()["tensors"]
    figures = {"residual/validation/overlay", "residual/validation/residual", "residual/identification/spectrum"}
    assert figures <= set(events.Tags()["images"])
    hparams = yaml.safe_load((run / "hparams.yaml").read_text())  # the config's model arguments
    assert hparams["bounds"] == {"zeta": [0.001, 5.0]} and hparams["max_iter"] == 20


@pytest.mark.slow
def test_validate_and_test_commands_score_a_checkpoint(chebyshev_run, tmp_path):
    cli, run = chebyshev_run
    config = ROOT / "experiments/paper/alpha4_chebyshev.yaml"
    checkpoint = str(run / "checkpoints/last.ckpt")
    tested = run_lightning(["test", *short(config, tmp_path, duration=40.0), "--ckpt_path", checkpoint])
    metrics = tested.trainer.callback_metrics
    expected = 100 * cli.model.record_mismatch(cli.datamodule.records("test"))
    assert float(metrics["residual/test/mismatch_pct"]) == pytest.approx(expected, rel=1e-9)
    validated = run_lightning(["validate", *short(config, tmp_path, duration=40.0), "--ckpt_path", checkpoint])
    assert "residual/validation/mismatch_pct" in validated.trainer.callback_metrics


@pytest.mark.slow
def test_a_resumed_run_ends_where_an_uninterrupted_run_ends(tmp_path):
    config = ROOT / "experiments/paper/alpha4_mlp_output.yaml"
    whole = run_lightning(["fit", *short(config, tmp_path / "whole", epochs=8)]).model
    run_lightning(["fit", *short(config, tmp_path / "split", epochs=4)])
    checkpoint = run_dir(tmp_path / "split") / "checkpoints" / "last.ckpt"
    resumed = run_lightning(["fit", *short(config, tmp_path / "split", epochs=8), "--ckpt_path", str(checkpoint)])
    assert resumed.trainer.current_epoch == 8
    for name, value in whole.state_dict().items():
        assert torch.allclose(resumed.model.state_dict()[name], value, rtol=0, atol=1e-12), name


@pytest.mark.slow
def test_ddp_across_two_cpu_processes_fits_the_physics(tmp_path):
    config = tmp_path / "ddp.yaml"
    config.write_text(
        f"""
seed_everything: 0
trainer:
  max_epochs: 3
  accelerator: cpu
  strategy: ddp
  devices: 2
  enable_progress_bar: false
  logger: {{class_path: lightning.pytorch.loggers.TensorBoardLogger, init_args: {{save_dir: {tmp_path}, name: ddp}}}}
model:
  class_path: torchpaml._training.PhysicsFit
  init_args:
    physics: {{class_path: torchpaml.Oscillator, init_args: {{zeta: 1.0, omega0: 2.0, learn: [zeta]}}}}
data:
  train:
    class_path: torchpaml._training.Simulated
    init_args:
      system: {{class_path: torchpaml.Oscillator, init_args: {{zeta: 0.4, omega0: 2.0, learn: []}}}}
      signal: pseudorandom
      seeds: [0, 1]
      duration: 10.0
"""
    )
    done = subprocess.run([sys.executable, "-m", "torchpaml", "fit", "--config", str(config)], capture_output=True,
                          text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "MEMBER: 2/2" in done.stdout + done.stderr  # two processes, one record each
    checkpoint = torch.load(run_dir(tmp_path) / "checkpoints" / "last.ckpt", weights_only=False)
    assert checkpoint["physical_parameters"]["zeta"] == pytest.approx(0.4, rel=1e-6)


@pytest.mark.parametrize(
    "override, message",
    [
        ("--data.train.init_args.signal=square", "square"),
        ("--data.train=torchpaml._training.Files", "paths"),
    ],
)
def test_bad_configs_exit_non_zero_with_the_reason(tmp_path, override, message):
    config = ROOT / "experiments/paper/alpha4_chebyshev.yaml"
    done = subprocess.run([sys.executable, "-m", "torchpaml", "fit", "--config", str(config), override],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode != 0
    assert message in done.stderr


def test_a_missing_data_file_exits_2_and_names_the_file(tmp_path):
    config = ROOT / "experiments/paper/alpha4_chebyshev.yaml"
    missing = tmp_path / "nowhere.csv"
    done = subprocess.run([sys.executable, "-m", "torchpaml", "fit", "--config", str(config),
                           "--data.train=torchpaml._training.Files", f"--data.train.paths=[{missing}]",
                           "--trainer.logger=false"], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 2
    assert f"no such file: {missing}" in done.stderr
