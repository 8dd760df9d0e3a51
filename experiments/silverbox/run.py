r"""Silverbox (an electronic Duffing oscillator, measured): diagnose the linear oscillator, add what is found.

    python experiments/silverbox/run.py --out DIR [--data PATH] [--shortlist K] [--discover]

The protocol is the registered :data:`BENCHMARK` (:mod:`torchpaml.leaderboard`; the data:
``shared/data/silverbox/README.md``): ``train_multisine`` for training, its last 20 % held out inside it for
validation; ``test_multisine``, ``test_arrow_no_extrapolation`` and ``test_arrow_full`` for the test. On each test
record the first 50 samples may set the initial state: the model's state is estimated on them and the remaining
samples are scored (:meth:`~torchpaml.leaderboard.Benchmark.score`).

1. The physics: :class:`~torchpaml._physics.Oscillator`, $\ddot y + 2\zeta\omega_0\dot y + \omega_0^2 y = g u$,
   all three learnable, started from the measured frequency response (:func:`frequency_response_start`).
2. :func:`~torchpaml.diagnose` with the library's effects, each record's initial state estimated (``Estimate()``:
   the training record starts mid-signal, where a start from rest made its first 100 samples 90 % of the fit's
   cost): the ladder adds what the validation asks for; the Chebyshev residual goes on the first and the last rung;
   the probes say where what is left points.
3. Every rung, the hybrid and every probe's extension are scored on the test records.
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

plus the leaderboard's fields (``schema_version``, ``benchmark``, ``protocol``, ``hybrid``, ``goal`` with what
limits the figure, the registry's rule on the measured figures (:func:`~torchpaml.leaderboard.diagnosed_goal`, with
the noise floor below), ``probes``; :mod:`torchpaml.leaderboard`) and ``noise_floor {rms, samples}``: the
output noise's RMS in mV, estimated on the training record where its input repeats at the period
(:func:`~torchpaml.leaderboard.noise_floor`)

and the diagnosis folder ``DIR/diagnosis/`` (report.html, figures/, tensorboard/, diagnosis.json).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from torchpaml import (Diagnosis, Discoverer, Estimate, Oscillator, Ranker, Record, default_effects, diagnose,
                       write_report)
from torchpaml.cli.progress import progress_lines
from torchpaml.leaderboard import (SCHEMA_VERSION, arguments, benchmark, diagnosed_goal, hybrid_entry, ladder_entries,
                                   noise_floor, tried_entries, write_result)
from torchpaml.report import diagnosis_to_dict, discovery_to_dict

BENCHMARK = benchmark("silverbox")
DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / BENCHMARK.folder
#: Samples per period of the multisine realisations (the data README).
PERIOD = 8192


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


def nrmse(rmse: dict[str, float], tests: dict[str, Record]) -> dict[str, float]:
    """Each test figure over the standard deviation of its record's scored output: the RMSE as a share of the
    signal."""
    return {name: value / BENCHMARK.scale / float(tests[name].y[BENCHMARK.init_window:, 0].std())
            for name, value in rmse.items()}


def diagnosed(train: Record, validation: Record, shortlist: int = 2) -> Diagnosis:
    """The diagnosis of the leaderboard's Silverbox run, its discovery aside (also
    ``benchmarks/bench_same_answer.py``'s)."""
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    return diagnose(frequency_response_start(train), default_effects(), train, validation,
                    ranker=Ranker(shortlist=shortlist), initial_state=Estimate(), alpha=alpha)


def main(argv: list[str] | None = None) -> dict:
    parser = arguments(BENCHMARK, __doc__, DATA)
    parser.add_argument("--discover", action="store_true", help="also discover a force outside the library")
    args = parser.parse_args(argv)
    if not (args.data / f"{BENCHMARK.train}.csv").is_file():
        parser.error(f"{args.data} has no {BENCHMARK.train}.csv; point --data at shared/data/{BENCHMARK.folder}")
    start = time.perf_counter()
    train, validation = BENCHMARK.split(Record.from_csv(args.data / f"{BENCHMARK.train}.csv"))
    tests = {name: Record.from_csv(args.data / f"{name}.csv", name=name) for name in BENCHMARK.tests}
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    diagnosis = diagnosed(train, validation, args.shortlist)
    write_report(diagnosis, args.out / "diagnosis")
    models = [{**row, "nrmse": nrmse(row["rmse"], tests)} for row in ladder_entries(BENCHMARK, diagnosis, tests)]
    final, alarm = diagnosis.ladder.final, diagnosis.hybrids[-1].adequacy
    floor, samples = noise_floor(train, PERIOD)
    result = {"schema_version": SCHEMA_VERSION, "benchmark": BENCHMARK.name, "protocol": BENCHMARK.protocol(),
              "noise_floor": {"rms": BENCHMARK.scale * floor, "samples": samples},
              "found": diagnosis.ladder.found, "models": models,
              "hybrid": hybrid_entry(BENCHMARK, final, [train], alpha, alarm, tests),
              "hybrids": diagnosis_to_dict(diagnosis)["hybrid"],
              "tried": tried_entries(BENCHMARK, diagnosis, tests)}
    result["goal"] = diagnosed_goal(BENCHMARK, diagnosis, models, result["hybrid"], floor=BENCHMARK.scale * floor)
    result["seconds"] = time.perf_counter() - start
    if args.discover:  # discovery alone, on the linear physics: which force is missing, in closed form
        found = diagnose(frequency_response_start(train), [], train, validation, discovery=Discoverer(),
                         prober=None).discovery
        discovered = found.discovered
        rmse = BENCHMARK.scores(discovered, tests) if discovered is not None else {}
        result["discovery"] = {**discovery_to_dict(found), "rmse": rmse, "nrmse": nrmse(rmse, tests)}
        print(f"discovered {found.expression}: " + ", ".join(f"{k} {v:.3f} mV" for k, v in rmse.items()), flush=True)
        result["seconds"] = time.perf_counter() - start
    return write_result(args.out, result, diagnosis.verdict)


if __name__ == "__main__":
    with progress_lines(Path(__file__).parent.name):  # the diagnosis' steps on stderr, with the seconds
        main()
