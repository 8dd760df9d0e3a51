r"""The contrast experiment: the orthogonal residual against the MLP baselines, two-stage and joint.

    python experiments/contrast/run.py --out DIR [--quick] [--jobs N] [--only PREFIX ...]

Every run goes through ``torchpaml fit`` (LightningCLI) with a config of ``experiments/paper/`` and is
its own TensorBoard run under ``DIR/tensorboard/`` (``tensorboard --logdir DIR/tensorboard`` overlays
them). Writes ``DIR/contrast.json``, a list of rows

    {"alpha", "residual": "chebyshev" | "mlp_output" | "mlp_ode", "scheme": "two_stage" | "joint",
     "input": "sine" | "pseudorandom", "zeta_init", "zeta_hat", "mismatch_train", "mismatch_validation"}

(mismatch as a fraction over the whole training / validation records), and ``DIR/contrast.md``.

* two-stage, at alpha = 4 and 10, trained on a pseudorandom record: zeta from stage 1 on the sine;
* joint, at alpha = 4, trained on the sine (the witness input) from zeta = 0.5x, 1x and 2x the
  physics-only estimate (a PhysicsFit run first).

Runs are spread over ``--jobs`` processes (default 2), one thread each, longest first.
``--quick`` shortens every run to a couple of epochs on 20 s records (a smoke test, not a result).
``--only PREFIX ...`` re-trains the matching runs and keeps the other rows of ``DIR/contrast.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import torch

from torchpaml.cli.lightning import run_lightning

CONFIGS = Path(__file__).resolve().parents[1] / "paper"
RESIDUALS = ("chebyshev", "mlp_output", "mlp_ode")
#: Seconds per run as this script measured them (two at a time on this machine's two cores), only to start
#: the longest first so that the two processes end together.
SECONDS = {"joint_alpha4_mlp_output": 91, "two_stage_alpha10_mlp_ode": 87, "two_stage_alpha10_mlp_output": 87,
           "two_stage_alpha4_mlp_output": 82, "two_stage_alpha4_mlp_ode": 81, "joint_alpha4_mlp_ode": 80,
           "two_stage_alpha10_chebyshev": 15, "joint_alpha4_chebyshev": 9, "two_stage_alpha4_chebyshev": 6}
SHORT = ["--trainer.max_epochs", "2", "--trainer.check_val_every_n_epoch", "1"] + [
    f"--data.{split}.init_args.duration=20.0" for split in ("identification", "train", "validation", "test")
]


@dataclass(frozen=True)
class Run:
    """One ``torchpaml fit`` of the sweep and the row it gives."""

    name: str
    config: str
    alpha: float
    residual: str
    scheme: str
    signal: str
    zeta_init: float = 1.0
    overrides: tuple[str, ...] = ()

    @property
    def group(self) -> str:
        """The name ``--only`` matches: a joint run's without its starting zeta."""
        return group_of(self.scheme, self.alpha, self.residual)


def group_of(scheme: str, alpha: float, residual: str) -> str:
    """A run's group name from the fields of its row (see :attr:`Run.group`)."""
    return f"{scheme}_alpha{alpha:g}_{residual}"


def plan(estimate: float) -> list[Run]:
    """Every run in the table's order; the joint ones start zeta at 0.5x, 1x and 2x ``estimate``."""
    runs = [Run(f"two_stage_alpha{alpha}_{residual}", f"alpha{alpha}_{residual}", float(alpha), residual, "two_stage",
                "pseudorandom") for alpha in (4, 10) for residual in RESIDUALS]
    runs += [Run(f"joint_alpha4_{residual}_zeta{factor * estimate:.4f}", f"joint_alpha4_{residual}", 4.0, residual,
                 "joint", "sine", factor * estimate, (f"--model.init_args.physics.init_args.zeta={factor * estimate}",))
             for residual in RESIDUALS for factor in (0.5, 1.0, 2.0)]
    return runs


def fit(config: str, out: Path, run: str, quick: bool, *overrides: str):
    """One ``torchpaml fit`` run; returns the LightningCLI object (its model and data module)."""
    args = ["fit", "--config", str(CONFIGS / f"{config}.yaml"), "--trainer.enable_progress_bar", "false",
            f"--trainer.logger.init_args.save_dir={out / 'tensorboard'}", f"--trainer.logger.init_args.name={run}",
            *(SHORT if quick else []), *overrides]
    start = time.perf_counter()
    cli = run_lightning(args)
    print(f"{run}: {time.perf_counter() - start:.0f} s", flush=True)
    return cli


def train(run: Run, out: Path, quick: bool) -> dict:
    """Fit ``run`` and return its row (whole training and validation records, simulated from rest)."""
    cli = fit(run.config, out, run.name, quick, *run.overrides)
    model, data = cli.model, cli.datamodule
    return {
        "alpha": run.alpha,
        "residual": run.residual,
        "scheme": run.scheme,
        "input": run.signal,
        "zeta_init": run.zeta_init,
        "zeta_hat": model.physics.physical_parameters()["zeta"],
        "mismatch_train": model.record_mismatch(data.records("train")),
        "mismatch_validation": model.record_mismatch(data.records("validation")),
    }


def physics_estimate(out: Path, quick: bool) -> float:
    """zeta of the physics alone, fitted on the sine (the joint runs start from 0.5x, 1x and 2x it)."""
    return fit("alpha4_physics", out, "physics_alpha4", quick).model.physics.physical_parameters()["zeta"]


def one_thread() -> None:
    """Each worker computes on one core: the pool, not the operators, spreads the sweep over the machine."""
    torch.set_num_threads(1)


def contrast(out: Path, quick: bool, only: list[str] | None = None, jobs: int = 2) -> list[dict]:
    """Every run, spread over ``jobs`` processes; ``contrast.json`` is rewritten, in the table's order, after each
    run ends, so an interrupted sweep keeps its rows.

    With ``only`` (run-name prefixes), just the matching runs are trained; the other rows are
    taken from the existing ``contrast.json``.
    """
    path = out / "contrast.json"
    existing = json.loads(path.read_text()) if only and path.exists() else []

    def selected(run: Run) -> bool:
        return not only or any(run.group.startswith(prefix) or run.name.startswith(prefix) for prefix in only)

    def kept(group: str) -> list[dict]:
        return [r for r in existing if group_of(r["scheme"], r["alpha"], r["residual"]) == group]

    done: dict[str, dict] = {}

    def write(runs: list[Run]) -> list[dict]:
        rows, groups = [], []
        for run in runs:
            if selected(run):
                rows.extend([done[run.name]] if run.name in done else [])
            elif run.group not in groups:
                groups.append(run.group)
                rows.extend(kept(run.group))
        path.write_text(json.dumps(rows, indent=2))
        return rows

    with ProcessPoolExecutor(jobs, mp_context=get_context("spawn"), initializer=one_thread) as pool:
        joint = any(selected(run) for run in plan(1.0) if run.scheme == "joint")
        # without joint runs to train, a placeholder estimate only places the kept joint rows
        runs = plan(pool.submit(physics_estimate, out, quick).result() if joint else 1.0)
        pending = {pool.submit(train, run, out, quick): run
                   for run in sorted((r for r in runs if selected(r)), key=lambda r: -SECONDS.get(r.group, 0))}
        for future in as_completed(pending):
            done[pending[future].name] = future.result()
            write(runs)
    return write(runs)


def markdown(rows: list[dict]) -> str:
    starts = sorted(r["zeta_init"] for r in rows if r["scheme"] == "joint")
    lines = [
        f"Joint runs start ζ at 0.5×, 1× and 2× the physics-only estimate ζ̂ = {starts[len(starts) // 2]:.4f}."
        if starts else "",
        "",
        "| α | residual | scheme | input | ζ init | ζ̂ | mismatch train % | mismatch validation % |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['alpha']:g} | {r['residual']} | {r['scheme']} | {r['input']} | {r['zeta_init']:.4f} | "
            f"{r['zeta_hat']:.4f} | {100 * r['mismatch_train']:.2f} | {100 * r['mismatch_validation']:.2f} |"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--quick", action="store_true", help="a couple of epochs on short records (smoke test)")
    parser.add_argument("--jobs", type=int, default=2, help="runs trained at once, one process and one thread "
                        "each (default 2: this machine's cores)")
    parser.add_argument("--only", nargs="+", metavar="PREFIX",
                        help="train only the runs whose name starts with PREFIX (e.g. two_stage_alpha10); "
                             "the other rows are kept from DIR/contrast.json")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rows = contrast(out, args.quick, args.only, args.jobs)
    table = markdown(rows)
    (out / "contrast.md").write_text(table + "\n")
    print(table)
    elapsed = time.perf_counter() - start
    print(f"\n{len(rows)} rows, {elapsed:.0f} s; wrote {out / 'contrast.json'} and {out / 'contrast.md'}")


if __name__ == "__main__":
    main()
