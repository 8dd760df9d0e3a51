r"""Silverbox (an electronic Duffing oscillator, measured): diagnose the linear oscillator, add what is found.

    python experiments/silverbox/run.py --out DIR [--data PATH] [--shortlist K] [--discover]

The official split (``shared/data/silverbox/README.md``): ``train_multisine`` for training, its last
:data:`VALIDATION_SHARE` held out inside it for validation; ``test_multisine``,
``test_arrow_no_extrapolation`` and ``test_arrow_full`` for the test. On each test record the first
:data:`INIT_SAMPLES` samples may set the initial state: the model's state is estimated on them
(:func:`~torchpaml._fit.estimate_initial_state`) and the remaining samples are scored.

1. The physics: :class:`~torchpaml._physics.Oscillator`, $\ddot y + 2\zeta\omega_0\dot y + \omega_0^2 y = g u$,
   all three learnable, started from the measured frequency response (:func:`frequency_response_start`).
2. :func:`~torchpaml._diagnostics.diagnose` with the twelve library effects: the ladder adds what the
   validation asks for; the Chebyshev residual goes on the first and the last rung.
3. Every rung is scored on the test records.
4. With ``--discover``, the discovery of a force outside the library
   (:func:`~torchpaml._diagnostics.discover_missing_force`) runs too; its model is scored on the test
   records and ``discovery`` is added to the JSON (``discovery.json``'s content, with ``rmse``/``nrmse``).

Writes ``DIR/silverbox.json``::

    {"found": [effects added, in order],
     "models": [{"model", "equation", "parameters", "uncertainty", "substeps",
                 "rmse": {"test_multisine": mV, "test_arrow_no_extrapolation": mV, "test_arrow_full": mV},
                 "nrmse": {...: RMSE / std(y) over the scored samples}}],   # physics alone first, final model last
     "hybrids": [the Chebyshev residual on the first and last rung, on validation, with the alarm],
     "seconds": wall time}

plus the leaderboard's fields (``schema_version``, ``benchmark``, ``protocol``, ``hybrid``: the final model with the
orthogonal residual on the test records; ``goal``, with what limits the figure, :func:`goal`; :mod:`leaderboard`) and
``noise_floor {rms, samples}``: the output noise's RMS
in mV, estimated on the training record where its input repeats (:func:`noise_floor`)

and the diagnosis folder ``DIR/diagnosis/`` (report.html, figures/, tensorboard/, diagnosis.json).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the leaderboard's contract, beside the experiments

from leaderboard import SCHEMA_VERSION, arguments, goal_entry, hybrid_entry, probe_entries, protocol, write_result  # noqa: E402

from torchpaml.cli.progress import progress_lines  # noqa: E402
from torchpaml import (
    Auto,
    Discoverer,
    Oscillator,
    Ranker,
    Record,
    Solver,
    default_effects,
    diagnose,
    estimate_initial_state,
    simulate_record,
    write_report,
)
from torchpaml.report import diagnosis_to_dict, discovery_to_dict

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "silverbox"
TESTS = ("test_multisine", "test_arrow_no_extrapolation", "test_arrow_full")
VALIDATION_SHARE = 0.2
INIT_SAMPLES = 50
#: Samples per period of the multisine realisations (the data README).
PERIOD = 8192
#: The leaderboard's goal on :data:`GOAL_SPLIT`, mV.
GOAL, GOAL_SPLIT = 0.40, "test_multisine"


def frequency_response_start(record: Record) -> Oscillator:
    r"""An :class:`Oscillator` started from the record's empirical transfer function $|H| = |Y/U|$.

    Only the excited bins count (above 0 Hz, $|U|$ above 10 % of its maximum there): $\omega_0$ at the peak of $|H|$,
    $g = \omega_0^2 |H(0)|$ with $|H(0)|$ the median gain of the lowest excited decade, and
    $\zeta = |H(0)| / (2 |H(\omega_0)|)$ from the resonance's height.
    """
    fs = 1 / record.dt
    U, Y = np.fft.rfft(record.u[:, 0].numpy()), np.fft.rfft(record.y[:, 0].numpy())
    f = np.fft.rfftfreq(len(record.t), 1 / fs)
    excited = (f > 0) & (np.abs(U) > 0.1 * np.abs(U[1:]).max())
    gain = np.where(excited, np.abs(Y) / np.where(excited, np.abs(U), 1.0), 0.0)
    peak = int(np.argmax(gain))
    lowest = f[excited].min()
    static = float(np.median(gain[excited & (f < 10 * lowest)]))
    omega0 = 2 * math.pi * f[peak]
    zeta = min(max(static / (2 * gain[peak]), 1e-3), 1.0)
    return Oscillator(zeta=zeta, omega0=omega0, gain=static * omega0**2, learn=("zeta", "omega0", "gain"))


def split(record: Record) -> tuple[Record, Record]:
    """The first 1 - VALIDATION_SHARE of ``record`` for training, the rest for validation."""
    cut = int(round((1 - VALIDATION_SHARE) * len(record.t)))
    return record.window(0, cut, "train"), record.window(cut, None, "validation")


def test_scores(model, tests: dict[str, Record], solver: Solver | None = None
                ) -> tuple[dict[str, float], dict[str, float]]:
    """RMSE in mV and NRMSE (RMSE / std y) of a fitted model on each test record, after the first INIT_SAMPLES;
    ``solver``: the one its fit resolved (``PhysicsEstimate.solver``)."""
    rmse, nrmse = {}, {}
    for name, record in tests.items():
        y_model = simulate_record(model, record, test_start(model, solver, record), solver=solver)[0]
        rmse[name] = output_rmse_mv(record, y_model)
        nrmse[name] = rmse[name] / 1000 / float(record.y[INIT_SAMPLES:, 0].std())
    return rmse, nrmse


def noise_floor(record: Record, period: int = PERIOD, window: int = 64) -> tuple[float, int]:
    r"""The output noise's RMS in mV, from the places where the record's input repeats at lag ``period``: the
    multisine's realisations are each preceded by the end of their own period, so there $u_k \approx u_{k+P}$ and,
    once the resonance has settled (the second half of each such run), $y_k - y_{k+P}$ is the difference of two
    noise samples: the floor is its RMS over $\sqrt 2$. Also returns how many samples it rests on."""
    u, y = record.u[:, 0].numpy(), record.y[:, 0].numpy()
    gap = np.abs(u[:-period] - u[period:])
    mean_gap = np.convolve(gap, np.ones(window) / window, mode="same")
    repeats = np.nonzero(mean_gap < 0.1 * np.sqrt(np.mean(u**2)))[0]
    runs = [run for run in np.split(repeats, np.nonzero(np.diff(repeats) > 1)[0] + 1) if len(run) > 2 * window]
    differences = np.concatenate([y[run[len(run) // 2:]] - y[run[len(run) // 2:] + period] for run in runs])
    return 1000 * float(differences.std()) / math.sqrt(2), len(differences)


def test_start(model, solver: Solver | None, record: Record):
    """The state that best explains the first :data:`INIT_SAMPLES` samples of ``record``, the parameters fixed."""
    return estimate_initial_state(model, record, INIT_SAMPLES, solver=Auto(start=solver))


def output_rmse_mv(record: Record, y_model) -> float:
    """The benchmark's metric: RMSE of the output in mV after the initialisation window."""
    return 1000 * float((record.y - y_model)[INIT_SAMPLES:, 0].square().mean().sqrt())


def goal(result: dict) -> dict:
    """:data:`GOAL` on test_multisine, and what limits the figure: the model class where the error stands well above
    the noise floor and an input-driven residual removes part of it on test (the error is a response to the
    input that the grey box does not express, not noise)."""
    final, floor = result["models"][-1]["rmse"][GOAL_SPLIT], result["noise_floor"]["rms"]
    hybrid = result["hybrid"]["rmse"][GOAL_SPLIT]
    evidence = {"final": final, "noise_floor": floor, "final_over_noise_floor": final / floor,
                "with_orthogonal_residual": hybrid}
    explanation = (f"the model class: the final grey box's error ({final:.3g} mV) is {final / floor:.1f} times the "
                   f"output noise floor ({floor:.3g} mV)")
    if hybrid is not None:
        explanation += (f", and an input-driven residual (the Chebyshev-Hammerstein model) removes "
                        f"{1 - hybrid / final:.0%} of it on test ({hybrid:.3g} mV): that part of the error is a "
                        f"response to the input that the physics does not express. The residual's alarm rejects "
                        f"the hybrid on the training records, so its figure is not quoted as the model's accuracy")
    return goal_entry(GOAL, GOAL_SPLIT, result["models"], result["hybrid"], "model class", evidence, explanation)


def main(argv: list[str] | None = None) -> dict:
    parser = arguments(__doc__, DATA)
    parser.add_argument("--discover", action="store_true", help="also discover a force outside the library")
    args = parser.parse_args(argv)
    if not (args.data / "train_multisine.csv").is_file():
        parser.error(f"{args.data} has no train_multisine.csv; point --data at shared/data/silverbox")
    start = time.perf_counter()
    train, validation = split(Record.from_csv(args.data / "train_multisine.csv"))
    tests = {name: Record.from_csv(args.data / f"{name}.csv") for name in TESTS}
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    diagnosis = diagnose(frequency_response_start(train), default_effects(), train, validation,
                         ranker=Ranker(shortlist=args.shortlist), alpha=alpha)
    write_report(diagnosis, args.out / "diagnosis")
    models = []
    content = diagnosis_to_dict(diagnosis)  # its uncertainty: null where a parameter is not determined
    for step, rung in zip(diagnosis.ladder.steps, content["ladder"], strict=True):
        rmse, nrmse = test_scores(step.model, tests, step.solver)
        models.append({"model": step.name, "equation": step.equation, "parameters": step.parameters,
                       "uncertainty": rung["uncertainty"], "substeps": step.solver.substeps, "rmse": rmse,
                       "nrmse": nrmse})
        print(f"{step.name}: " + ", ".join(f"{k} {v:.3f} mV" for k, v in rmse.items()), flush=True)
    final, alarm = diagnosis.ladder.final, diagnosis.hybrids[-1].adequacy
    hybrid = hybrid_entry(final, [train], alpha, alarm,
                          {name: (r, test_start(final.model, final.solver, r)) for name, r in tests.items()},
                          output_rmse_mv)
    result = {"schema_version": SCHEMA_VERSION, "benchmark": "silverbox",
              "protocol": protocol("train_multisine (its last 20 % for validation)", list(TESTS), INIT_SAMPLES,
                                   "RMSE of the output, free run", "mV"),
              "noise_floor": dict(zip(("rms", "samples"), noise_floor(train), strict=True)),
              "found": diagnosis.ladder.added, "models": models, "hybrid": hybrid, "hybrids": content["hybrid"]}
    result["goal"] = goal(result)
    result["probes"] = probe_entries(diagnosis.probes, lambda score: test_scores(score.model, tests, score.solver)[0])
    result["seconds"] = time.perf_counter() - start
    if args.discover:  # discovery alone, on the linear physics: which force is missing, in closed form
        found = diagnose(frequency_response_start(train), [], train, validation, discovery=Discoverer()).discovery
        discovered = found.discovered
        rmse, nrmse = test_scores(discovered.model, tests, discovered.solver) if discovered is not None else ({}, {})
        result["discovery"] = {**discovery_to_dict(found), "rmse": rmse, "nrmse": nrmse}
        print(f"discovered {found.expression}: " + ", ".join(f"{k} {v:.3f} mV" for k, v in rmse.items()), flush=True)
        result["seconds"] = time.perf_counter() - start
    return write_result(args.out, result, diagnosis.verdict)


if __name__ == "__main__":
    with progress_lines(Path(__file__).parent.name):  # the diagnosis' steps on stderr, with the seconds
        main()
