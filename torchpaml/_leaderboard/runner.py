r"""The registry's own protocol: a benchmark whose entry names a ``model`` (and no experiment script) is run from its
entry file and its data alone.

    run_benchmark(benchmark, out, data)

reads the training record (its last ``validation_share`` held out for validation) and the test records from
``data``, diagnoses the entry's physics with its candidates (:func:`~torchpaml.diagnose`, the Chebyshev residual's
domain 5 % beyond the largest training input), writes the diagnosis folder ``out/diagnosis/`` and the leaderboard's
fields (:mod:`~torchpaml._leaderboard.result`) as ``out/<name>.json``, with the goal's limit read from the diagnosis
(:func:`diagnosed_goal`).
"""

from __future__ import annotations

import time
from pathlib import Path

from torchpaml._data import Record
from torchpaml._diagnostics.diagnosis import Diagnosis, diagnose
from torchpaml._diagnostics.ranking.ranker import Ranker
from torchpaml._errors import ConfigurationError
from torchpaml._leaderboard.benchmark import Benchmark
from torchpaml._leaderboard.limit import LimitFigures, limit_of
from torchpaml._leaderboard.result import (SCHEMA_VERSION, goal_entry, hybrid_entry, ladder_entries, tried_entries,
                                           write_result)
from torchpaml._physics.effects import default_effects
from torchpaml._render.report import write_report
from torchpaml._render.schema import diagnosis_to_dict

__all__ = ["diagnosed_goal", "run_benchmark"]


def run_benchmark(benchmark: Benchmark, out: Path, data: Path, shortlist: int = 2) -> dict:
    """Run ``benchmark``'s protocol from its entry (module docstring) on the records in ``data``; the result
    written to ``out/<name>.json``. ``shortlist``: the candidates refitted per rung."""
    if benchmark.model is None:
        raise ConfigurationError(f"{benchmark.name} is run by its script {benchmark.experiment}, not by the registry's "
                                 "protocol; give its entry a model (Benchmark(model=lambda train: physics))")
    missing = [stem for stem in (benchmark.train, *benchmark.tests) if not (data / f"{stem}.csv").is_file()]
    if missing:
        raise ConfigurationError(f"{data} lacks {', '.join(f'{stem}.csv' for stem in missing)}; point --data at the "
                                 f"{benchmark.title} data (shared/data/{benchmark.folder})")
    start = time.perf_counter()
    train, validation = benchmark.split(Record.from_csv(data / f"{benchmark.train}.csv", "train", hold=benchmark.hold))
    tests = {name: Record.from_csv(data / f"{name}.csv", name, hold=benchmark.hold) for name in benchmark.tests}
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    candidates = default_effects() if benchmark.candidates is None else benchmark.candidates()
    diagnosis = diagnose(benchmark.model(train), candidates, train, validation, ranker=Ranker(shortlist=shortlist),
                         initial_state=benchmark.initial_state, alpha=alpha)
    write_report(diagnosis, out / "diagnosis")
    models = ladder_entries(benchmark, diagnosis, tests)
    hybrid = hybrid_entry(benchmark, diagnosis.ladder.final, [train], alpha, diagnosis.hybrids[-1].adequacy, tests)
    result = {"schema_version": SCHEMA_VERSION, "benchmark": benchmark.name, "protocol": benchmark.protocol(),
              "found": diagnosis.ladder.found, "models": models, "hybrid": hybrid,
              "hybrids": diagnosis_to_dict(diagnosis)["hybrid"],
              "goal": diagnosed_goal(benchmark, diagnosis, models, hybrid),
              "tried": tried_entries(benchmark, diagnosis, tests), "seconds": time.perf_counter() - start}
    return write_result(out, result, diagnosis.verdict)


def diagnosed_goal(benchmark: Benchmark, diagnosis: Diagnosis, models: list[dict], hybrid: dict,
                   floor: float | None = None, evidence: dict[str, float] | None = None,
                   notes: tuple[str, ...] = ()) -> dict:
    """The goal entry (:func:`~torchpaml._leaderboard.result.goal_entry`) whose limit and sentence are the one rule's
    (:func:`~torchpaml._leaderboard.limit.limit_of`) on the measured figures: the final grey box's error on the
    headline split, the diagnosis' verdict and validation mismatch, the error with the input-driven residual
    (``hybrid``), the place the probes name (where they ran) and ``floor``, the output noise's RMS read on the
    input's repeats in the benchmark's unit (``None``: not measured; the diagnosis' verdict stands in).

    ``evidence``: more measured numbers a protocol adds (they do not enter the rule); ``notes``: sentences computed
    from them (e.g. :func:`~torchpaml._leaderboard.result.agreement_evidence`'s), appended to the rule's."""
    split, best = benchmark.goal_split, None if diagnosis.probes is None else diagnosis.probes.best
    figures = LimitFigures(error=models[-1]["rmse"][split], unit=benchmark.unit,
                           adequacy=diagnosis.hybrids[-1].adequacy, validation=diagnosis.ladder.final.nrmse_validation,
                           floor=floor, with_residual=hybrid["rmse"][split],
                           probe=None if best is None else (best.place, best.fitted, best.gain))
    kind, measured, sentence = limit_of(figures)
    extra = dict(evidence or {})
    if extra:
        notes = (f"also measured: {', '.join(f'{name} {value:.4g}' for name, value in extra.items())}", *notes)
    return goal_entry(benchmark, models, hybrid, kind, measured | extra, "; ".join([sentence, *notes]))
