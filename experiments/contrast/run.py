r"""The contrast experiment: the orthogonal residual against the MLP baselines, two-stage and joint.

    python experiments/contrast/run.py --out DIR [--quick]

Every run goes through ``torchpaml fit`` (LightningCLI) with a config of ``experiments/paper/`` and is
its own TensorBoard run under ``DIR/tensorboard/`` (``tensorboard --logdir DIR/tensorboard`` overlays
them). Writes ``DIR/contrast.json``, a list of rows

    {"alpha", "residual": "chebyshev" | "mlp_output" | "mlp_ode", "scheme": "two_stage" | "joint",
     "input": "sine" | "pseudorandom", "zeta_init", "zeta_hat", "mismatch_train", "mismatch_validation"}

(mismatch as a fraction over the whole training / validation records), and ``DIR/contrast.md``.

* two-stage, at alpha = 4 and 10, trained on a pseudorandom record: zeta from stage 1 on the sine;
* joint, at alpha = 4, trained on the sine (the witness input) from zeta = 0.5x, 1x and 2x the
  physics-only estimate (a PhysicsFit run first).

``--quick`` shortens every run to a couple of epochs on 20 s records (a smoke test, not a result).
``--only PREFIX ...`` re-trains the matching runs and keeps the other rows of ``DIR/contrast.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from torchpaml.training.cli import run_lightning

CONFIGS = Path(__file__).resolve().parents[1] / "paper"
RESIDUALS = ("chebyshev", "mlp_output", "mlp_ode")
SHORT = ["--trainer.max_epochs", "2", "--trainer.check_val_every_n_epoch", "1"] + [
    f"--data.{split}.init_args.duration=20.0" for split in ("identification", "train", "validation", "test")
]


def fit(config: str, out: Path, run: str, quick: bool, *overrides: str):
    """One ``torchpaml fit`` run; returns the LightningCLI object (its model and data module)."""
    args = ["fit", "--config", str(CONFIGS / f"{config}.yaml"), "--trainer.enable_progress_bar", "false",
            f"--trainer.logger.init_args.save_dir={out / 'tensorboard'}", f"--trainer.logger.init_args.name={run}",
            *(SHORT if quick else []), *overrides]
    start = time.perf_counter()
    cli = run_lightning(args)
    print(f"{run}: {time.perf_counter() - start:.0f} s", flush=True)
    return cli


def row(cli, alpha: float, residual: str, scheme: str, signal: str, zeta_init: float) -> dict:
    model, data = cli.model, cli.datamodule
    return {
        "alpha": alpha,
        "residual": residual,
        "scheme": scheme,
        "input": signal,
        "zeta_init": zeta_init,
        "zeta_hat": model.physics.physical_parameters()["zeta"],
        "mismatch_train": model.record_mismatch(data.records("train")),
        "mismatch_validation": model.record_mismatch(data.records("validation")),
    }


def contrast(out: Path, quick: bool, only: list[str] | None = None) -> list[dict]:
    """Every run, in order; ``contrast.json`` is rewritten after each, so an interrupted sweep keeps its rows.

    With ``only`` (run-name prefixes), just the matching runs are trained; the other rows are
    taken from the existing ``contrast.json``.
    """
    path = out / "contrast.json"
    existing = json.loads(path.read_text()) if only and path.exists() else []
    rows = []

    def selected(run: str) -> bool:
        return not only or any(run.startswith(prefix) for prefix in only)

    def keep(*new: dict) -> None:
        rows.extend(new)
        path.write_text(json.dumps(rows, indent=2))

    for alpha in (4, 10):
        for residual in RESIDUALS:
            run = f"two_stage_alpha{alpha}_{residual}"
            if selected(run):
                keep(row(fit(f"alpha{alpha}_{residual}", out, run, quick), float(alpha), residual, "two_stage",
                         "pseudorandom", 1.0))
            else:
                key = ("two_stage", alpha, residual)
                keep(*[r for r in existing if (r["scheme"], r["alpha"], r["residual"]) == key])
    joint = {residual: f"joint_alpha4_{residual}" for residual in RESIDUALS}
    if any(selected(run) for run in joint.values()):
        estimate = fit("alpha4_physics", out, "physics_alpha4", quick).model.physics.physical_parameters()["zeta"]
    for residual, run in joint.items():
        if not selected(run):
            keep(*[r for r in existing if (r["scheme"], r["residual"]) == ("joint", residual)])
            continue
        for factor in (0.5, 1.0, 2.0):
            start = factor * estimate
            cli = fit(f"joint_alpha4_{residual}", out, f"{run}_zeta{start:.4f}", quick,
                      f"--model.init_args.physics.init_args.zeta={start}")
            keep(row(cli, 4.0, residual, "joint", "sine", start))
    return rows


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
    parser.add_argument("--only", nargs="+", metavar="PREFIX",
                        help="train only the runs whose name starts with PREFIX (e.g. two_stage_alpha10); "
                             "the other rows are kept from DIR/contrast.json")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rows = contrast(out, args.quick, args.only)
    table = markdown(rows)
    (out / "contrast.md").write_text(table + "\n")
    print(table)
    elapsed = time.perf_counter() - start
    print(f"\n{len(rows)} rows, {elapsed:.0f} s; wrote {out / 'contrast.json'} and {out / 'contrast.md'}")


if __name__ == "__main__":
    main()
