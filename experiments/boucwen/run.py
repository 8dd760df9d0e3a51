r"""Bouc-Wen hysteresis benchmark (simulated): diagnose a user's linear mass-spring-damper, add what is found.

    python experiments/boucwen/run.py --out DIR [--data PATH] [--shortlist K]

The protocol is the registered :data:`BENCHMARK` (:mod:`torchpaml.leaderboard`; the data:
``shared/data/boucwen/README.md``): ``train_multisine_forgione`` (5 periods of a random-phase multisine, 40 960
samples at 750 Hz, with output noise), its first four periods for training and its last for validation; the
official test signals ``test_multisine`` (one steady-state period, noiseless) and ``test_sinesweep`` (from rest,
noiseless) are touched only to score, as the benchmark defines them: ``test_multisine`` in its periodic steady state
(the input applied twice from rest, the second period scored: the linear part's transient decays in 0.4 s, the
period lasts 10.9 s), ``test_sinesweep`` from rest. The metric is the RMS simulation error in metres.

1. The physics: the user's :class:`MassSpringDamper` (``mass_spring_damper.py``), $m\ddot y + c\dot y + k y = u$,
   started from the training record's frequency response, not from the data-generating values.
2. :func:`~torchpaml.diagnose` with the library's effects: the ladder adds what the validation asks for; each
   record's initial state is estimated (the training multisine does not start at rest); the Chebyshev residual
   goes on the first and the last rung; the probes say where what is left points.
3. Every rung, the hybrid and every probe's extension are scored on the test records (:meth:`Benchmark.score`).

Writes ``DIR/boucwen.json``: the leaderboard's fields (:mod:`torchpaml.leaderboard`), ``found`` (the effects added,
in order) and ``hybrids`` (the Chebyshev residual on the first and last rung, on validation, with the alarm); and the
diagnosis folder ``DIR/diagnosis/``.
"""

from __future__ import annotations

import time
from pathlib import Path

from mass_spring_damper import frequency_response_start  # the user's physics, beside this script

from torchpaml import Estimate, Ranker, Record, default_effects, diagnose, simulate_record, write_report
from torchpaml.cli.progress import progress_lines
from torchpaml.leaderboard import (SCHEMA_VERSION, arguments, benchmark, goal_entry, hybrid_entry, ladder_entries,
                                   tried_entries, write_result)
from torchpaml.report import diagnosis_to_dict

BENCHMARK = benchmark("boucwen")
DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / BENCHMARK.folder


def goal(final, record: Record, models: list[dict], hybrid: dict) -> dict:
    """The goal on test_multisine, and what limits the figure: the training record's noise where the final model's
    error on its held-out last part is that noise (it fits the device to the noise), so that what remains on the
    noiseless test records is the parameter error that the noisy training record leaves."""
    y = simulate_record(final.model, record, final.train_states[0], solver=final.solver)[0]
    held = len(record.t) - int(round((1 - BENCHMARK.validation_share) * len(record.t)))
    held_out = float((record.y - y)[-held:, 0].square().mean().sqrt())
    test = models[-1]["rmse"][BENCHMARK.goal_split]
    explanation = (f"the noise floor of the training record: on its held-out last period the final model's error is "
                   f"{held_out:.3g} m, the measurement noise the data README states for it (8e-6 m RMS), so the "
                   f"model has fitted the device down to that noise; the test records are noiseless, and their "
                   f"error ({test:.3g} m) is what that noise leaves in the parameters")
    return goal_entry(BENCHMARK, models, hybrid, "noise floor", {"held_out_period": held_out, "test_multisine": test},
                      explanation)


def main(argv: list[str] | None = None) -> dict:
    parser = arguments(BENCHMARK, __doc__, DATA)
    args = parser.parse_args(argv)
    if not (args.data / f"{BENCHMARK.train}.csv").is_file():
        parser.error(f"{args.data} has no {BENCHMARK.train}.csv; point --data at shared/data/{BENCHMARK.folder}")
    start = time.perf_counter()
    record = Record.from_csv(args.data / f"{BENCHMARK.train}.csv", name="train")
    train, validation = BENCHMARK.split(record)
    tests = {name: Record.from_csv(args.data / f"{name}.csv", name=name) for name in BENCHMARK.tests}
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    diagnosis = diagnose(frequency_response_start(train), default_effects(), train, validation,
                         ranker=Ranker(shortlist=args.shortlist), initial_state=Estimate(), alpha=alpha)
    write_report(diagnosis, args.out / "diagnosis")
    models = ladder_entries(BENCHMARK, diagnosis, tests)
    final, alarm = diagnosis.ladder.final, diagnosis.hybrids[-1].adequacy
    hybrid = hybrid_entry(BENCHMARK, final, [train], alpha, alarm, tests)
    result = {"schema_version": SCHEMA_VERSION, "benchmark": BENCHMARK.name, "protocol": BENCHMARK.protocol(),
              "found": diagnosis.ladder.added, "models": models, "hybrid": hybrid,
              "hybrids": diagnosis_to_dict(diagnosis)["hybrid"], "goal": goal(final, record, models, hybrid),
              "tried": tried_entries(BENCHMARK, diagnosis, tests), "seconds": time.perf_counter() - start}
    return write_result(args.out, result, diagnosis.verdict)


if __name__ == "__main__":
    with progress_lines(Path(__file__).parent.name):  # the diagnosis' steps on stderr, with the seconds
        main()
