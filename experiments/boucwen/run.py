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

Writes ``DIR/boucwen.json``: the leaderboard's fields (:mod:`torchpaml.leaderboard`; ``goal``'s limit by the
registry's rule, :func:`~torchpaml.leaderboard.diagnosed_goal`, with the error on the training record's held-out
last period, :func:`held_out_error`, as ``held_out_period``), ``found`` (the effects added,
in order) and ``hybrids`` (the Chebyshev residual on the first and last rung, on validation, with the alarm); and the
diagnosis folder ``DIR/diagnosis/``.
"""

from __future__ import annotations

import time
from pathlib import Path

from mass_spring_damper import frequency_response_start  # the user's physics, beside this script

from torchpaml import Diagnosis, Estimate, Ranker, Record, default_effects, diagnose, simulate_record, write_report
from torchpaml.cli.progress import progress_lines
from torchpaml.leaderboard import (SCHEMA_VERSION, arguments, benchmark, diagnosed_goal, hybrid_entry, ladder_entries,
                                   tried_entries, write_result)
from torchpaml.report import diagnosis_to_dict

BENCHMARK = benchmark("boucwen")
DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / BENCHMARK.folder


def held_out_error(final, record: Record) -> float:
    """The final model's RMSE (m) on the training record's held-out last part, simulated on from the whole record's
    start."""
    y = simulate_record(final.model, record, final.train_states[0], solver=final.solver)[0]
    held = len(record.t) - int(round((1 - BENCHMARK.validation_share) * len(record.t)))
    return float((record.y - y)[-held:, 0].square().mean().sqrt())


def diagnosed(train: Record, validation: Record, shortlist: int = 2) -> Diagnosis:
    """The diagnosis of the leaderboard's Bouc-Wen run (also ``benchmarks/bench_same_answer.py``'s)."""
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    return diagnose(frequency_response_start(train), default_effects(), train, validation,
                    ranker=Ranker(shortlist=shortlist), initial_state=Estimate(), alpha=alpha)


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
    diagnosis = diagnosed(train, validation, args.shortlist)
    write_report(diagnosis, args.out / "diagnosis")
    models = ladder_entries(BENCHMARK, diagnosis, tests)
    final, alarm = diagnosis.ladder.final, diagnosis.hybrids[-1].adequacy
    hybrid = hybrid_entry(BENCHMARK, final, [train], alpha, alarm, tests)
    held_out = {"held_out_period": held_out_error(final, record)}
    goal = diagnosed_goal(BENCHMARK, diagnosis, models, hybrid, evidence=held_out)
    result = {"schema_version": SCHEMA_VERSION, "benchmark": BENCHMARK.name, "protocol": BENCHMARK.protocol(),
              "found": diagnosis.ladder.found, "models": models, "hybrid": hybrid,
              "hybrids": diagnosis_to_dict(diagnosis)["hybrid"], "goal": goal,
              "tried": tried_entries(BENCHMARK, diagnosis, tests), "seconds": time.perf_counter() - start}
    return write_result(args.out, result, diagnosis.verdict)


if __name__ == "__main__":
    with progress_lines(Path(__file__).parent.name):  # the diagnosis' steps on stderr, with the seconds
        main()
