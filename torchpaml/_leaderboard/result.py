"""The leaderboard's contract: what every benchmark's run writes, ``DIR/<benchmark>.json``::

    {"schema_version", "benchmark",
     "protocol": {"train", "test", "init_window", "metric", "unit"},
     "models": [{"model", "equation", "parameters", "uncertainty", "rmse": {<test split>: value}}],
     "hybrid": {"model", "accepted", "rmse": {<test split>: value or null}, "reason"},
     "goal": {"value", "split", "figure", "met", "limit": {"kind", "evidence", "explanation"}},
     "tried": [{"stage", "place", "hypothesis", "validation_gain", "rmse": {<test split>: value}, "kept", "named"}],
     "seconds"}

``models`` goes from the linear physics to the final grey box; ``hybrid`` is the final model with the orthogonal
residual of the paper on top (:func:`~torchpaml.analysis.hybrid_residual`, fitted on the training records only),
``accepted`` where the final rung's alarm recommends it (neither inadequate nor complete physics), and an RMSE of
``null`` where a test input leaves the residual's domain. ``goal`` holds the benchmark's goal on its headline split
(:func:`goal_entry`): the figure that counts (the hybrid's where its alarm accepts it, else the final grey box's),
whether it meets the goal, and what limits it: one of :data:`LIMITS`, with the measured numbers that show it, both
written by the one rule :func:`~torchpaml._leaderboard.limit.limit_of` (through
:func:`~torchpaml._leaderboard.runner.diagnosed_goal`).
``tried`` holds every hypothesis the diagnosis fitted (:func:`tried_entries`): each rung's refitted candidates, the
earlier effects tried out, the other paths of the ladder's beam, then the probes of where the final grey box's
mismatch points, each with its validation gain, its test figures, whether it is kept in the final grey box, and
whether the probes name its place; a protocol adds the hypotheses it tries beside the diagnosis
(:func:`hypothesis_entry`). Every figure is :meth:`Benchmark.score`'s.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path

import torch
from scipy.stats import spearmanr

from torchpaml._budget import Budget
from torchpaml._diagnostics.analysis.adequacy import Adequacy
from torchpaml._diagnostics.diagnosis import Diagnosis, hybrid_residual
from torchpaml._diagnostics.results import ModelScore
from torchpaml._data import Record
from torchpaml._data.simulation import simulate_record
from torchpaml._diagnostics.ranking.scoring import score_model
from torchpaml._errors import ConfigurationError, DomainError, SimulationError
from torchpaml._fit.initial_state import InitialState
from torchpaml._fit.physics_fit import fit_physics
from torchpaml._leaderboard.benchmark import Benchmark
from torchpaml._leaderboard.limit import LIMITS
from torchpaml._render.schema import diagnosis_to_dict

__all__ = ["LIMITS", "SCHEMA_VERSION", "arguments", "goal_entry", "hybrid_entry", "hypothesis_entry", "ladder_entries",
           "tried_entries", "validation_agreement", "agreement_evidence", "write_result"]

#: The version of the leaderboard fields; a change of their meaning raises it.
SCHEMA_VERSION = 1


def arguments(benchmark: Benchmark, doc: str, data: Path) -> argparse.ArgumentParser:
    """A benchmark run's command line: ``--out DIR``, ``--data PATH`` (default ``data``) and ``--shortlist K``."""
    parser = argparse.ArgumentParser(description=doc.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--data", type=Path, default=data, help=f"the {benchmark.title} data folder (default {data})")
    parser.add_argument("--shortlist", type=int, default=2, help="candidates refitted per rung (default 2)")
    return parser


def ladder_entries(benchmark: Benchmark, diagnosis: Diagnosis, tests: dict[str, Record]) -> list[dict]:
    """Every rung of the diagnosis' ladder as a leaderboard row, scored on ``tests`` (:meth:`Benchmark.scores`), its
    uncertainty as ``diagnosis.json`` writes it (``null`` where a parameter is not determined); each printed."""
    rows = []
    for step, rung in zip(diagnosis.ladder.steps, diagnosis_to_dict(diagnosis)["ladder"], strict=True):
        rmse = benchmark.scores(step, tests)
        rows.append({"model": step.name, "equation": step.equation, "parameters": step.parameters,
                     "uncertainty": rung["uncertainty"], "solver": type(step.solver).__name__,
                     "substeps": step.solver.substeps, "rmse": rmse})
        print(f"{step.name}: " + ", ".join(f"{k} {v:.4g} {benchmark.unit_of(k)}" for k, v in rmse.items()), flush=True)
    return rows


def hybrid_entry(benchmark: Benchmark, step: ModelScore, train: list[Record], alpha: float, alarm: Adequacy,
                 tests: dict[str, Record]) -> dict:
    """The final model ``step`` plus the Chebyshev-Hammerstein residual fitted on its training residual, scored on
    each test record as :meth:`Benchmark.score` scores a model; ``None`` where the test input leaves the residual's
    domain ``alpha``. ``accepted`` where the diagnosis' alarm on the final rung (``alarm``) recommends the hybrid:
    neither inadequate physics (the residual would hide it) nor complete physics (its residual is noise the
    orthogonal residual cannot reduce: the diagnosis says to use the physics alone, and a residual fitted to that
    noise scores by chance); ``reason``: its message."""
    residual, _ = hybrid_residual(step, train, alpha)
    rmse = {}
    for name, record in tests.items():
        prepared = benchmark.prepared(record)
        with torch.no_grad():
            start = benchmark.start_of(step.model, prepared, step.solver, step.train_states[0])
            y = simulate_record(step.model, prepared, start, solver=step.solver)[0]
            try:
                y = y + residual(prepared.elapsed, prepared.u[None])[0]
            except DomainError:
                rmse[name] = None
                continue
        rmse[name] = benchmark.metric_of(prepared, y)
    return {"model": f"{step.name} + ChebyshevHammerstein", "accepted": alarm.recommends_hybrid, "rmse": rmse,
            "reason": alarm.message}


def goal_entry(benchmark: Benchmark, models: list[dict], hybrid: dict, limit: str, evidence: dict[str, float],
               explanation: str) -> dict:
    """The benchmark's goal on its headline split: the figure that counts (the hybrid's where its alarm accepts it,
    else the final grey box's), whether it is at most the goal, and what limits it (one of :data:`LIMITS`;
    ``evidence``, the measured numbers that show it, in the benchmark's unit unless their name says otherwise)."""
    if limit not in LIMITS:
        raise ValueError(f"limit must be one of {LIMITS}, got {limit!r}")
    split = benchmark.goal_split
    figure = hybrid["rmse"][split] if hybrid["accepted"] and hybrid["rmse"][split] is not None else \
        models[-1]["rmse"][split]
    return {"value": benchmark.goal, "split": split, "figure": figure, "met": figure <= benchmark.goal,
            "limit": {"kind": limit, "evidence": evidence, "explanation": explanation}}


def tried_entries(benchmark: Benchmark, diagnosis: Diagnosis, tests: dict[str, Record]) -> list[dict]:
    """Every hypothesis the diagnosis fitted, each scored on ``tests`` (:meth:`Benchmark.scores`): on each rung of the
    ladder, the candidates it refitted (``stage`` ``"rung N"``) and the earlier effects tried out of its model
    (``"without EFFECT"``, :mod:`~torchpaml._diagnostics.ranking.removal`), each other path of the ladder's beam
    (``stage`` ``"beam"``, its effects joined by ``+``, its gain against the greedy path's end;
    :mod:`~torchpaml._diagnostics.ranking.beam`), and then the probes of where the final
    grey box's mismatch points (``stage`` ``"probe"``, with its ``place``); ``validation_gain``: the share by which
    it lowers its rung's validation mismatch; ``kept``: it is in the final grey box; ``named``: the place the probes name.
    Every choice was made on the validation records; the test figures are reported, not chosen on."""
    ladder = diagnosis.ladder
    rows, added, found = [], ladder.added, ladder.found
    for rung, ranking in enumerate(ladder.rankings):
        base = ranking.baseline.nrmse_validation
        for entry in (e for e in ranking.entries if e.refit is not None):
            rows.append({"stage": f"rung {rung + 1}", "place": None, "hypothesis": entry.effect,
                         "validation_gain": 1.0 - entry.refit.nrmse_validation / base,
                         "rmse": benchmark.scores(entry.refit, tests),
                         "kept": rung < len(added) and entry.effect == added[rung] and entry.effect in found,
                         "named": False})
    for removal in (r for r in ladder.removals if r.score is not None):
        rows.append({"stage": f"rung {removal.rung + 1}", "place": None, "hypothesis": f"without {removal.effect}",
                     "validation_gain": 1.0 - removal.nrmse_validation / removal.against,
                     "rmse": benchmark.scores(removal.score, tests), "kept": removal.removed, "named": False})
    greedy = next((end for end in ladder.beam if end.greedy), None)
    for end in (e for e in ladder.beam if not (e.greedy and e.chosen) and e.score is not None):
        rows.append({"stage": "beam", "place": None, "hypothesis": " + ".join(end.effects) or "the physics alone",
                     "validation_gain": 1.0 - end.nrmse_validation / greedy.nrmse_validation,
                     "rmse": benchmark.scores(end.score, tests), "kept": end.chosen, "named": False})
    probes = diagnosis.probes
    best = None if probes is None else probes.best
    for row in [] if probes is None else probes.rows:
        rmse = None if row.score is None else benchmark.scores(row.score, tests)
        rows.append({"stage": "probe", "place": row.place, "hypothesis": row.fitted or f"— ({row.note.split(';')[0]})",
                     "validation_gain": row.gain, "rmse": rmse,
                     "kept": False, "named": row is best})
    return rows


def hypothesis_entry(benchmark: Benchmark, stage: str, hypothesis: str, model, train: list[Record],
                     tests: dict[str, Record], *, initial_state: InitialState, baseline: ModelScore | None = None,
                     validation: Sequence[Record] = (), start_states: list[torch.Tensor] | None = None) -> dict:
    """A hypothesis a protocol tries beside the diagnosis (a user's effect on the final grey box; the final grey box
    refitted on the whole training record), as a row of ``tried``: ``model`` fitted on ``train`` from
    ``start_states`` (:func:`~torchpaml.fit_physics`), scored on ``tests`` and, where ``validation`` is given, on it
    as the diagnosis scores a candidate (``validation_gain`` over ``baseline``'s mismatch; ``None`` otherwise).
    Never kept: the diagnosis' final grey box stays the benchmark's model. Where its fit or its validation score
    blows up (a :class:`~torchpaml.SimulationError`), the row says so, without figures. Printed."""
    if validation and baseline is None:
        raise ConfigurationError("a hypothesis scored on validation needs the baseline its gain is measured against "
                                 "(baseline=, the final grey box's ModelScore)")
    try:
        fit = fit_physics(model, train, initial_state=initial_state, start_states=start_states,
                          budget=Budget(f"{stage}: fitting {hypothesis}"))  # no limit: its progress lines
        gain = None if not validation else 1.0 - score_model(
            model, fit, list(validation), initial_state=initial_state).nrmse_validation / baseline.nrmse_validation
    except SimulationError as error:  # as the ranking's refits: a fit or a validation score that blows up
        reason = str(error).split(":")[0]
        print(f"{stage}: {hypothesis}: failed ({reason})", flush=True)
        return {"stage": stage, "place": None, "hypothesis": f"{hypothesis} (failed: {reason})",
                "validation_gain": None, "rmse": None, "kept": False, "named": False}
    state = fit.initial_states[0] if fit.initial_states else None
    rmse = benchmark.scores_of(model, tests, solver=fit.solver, train_state=state)
    print(f"{stage}: {hypothesis}: " + ", ".join(f"{k} {v:.4g} {benchmark.unit_of(k)}" for k, v in rmse.items()) +
          ("" if gain is None else f" (validation gain {100 * gain:.1f} %)"), flush=True)
    return {"stage": stage, "place": None, "hypothesis": hypothesis, "validation_gain": gain, "rmse": rmse,
            "kept": False, "named": False}


def validation_agreement(tried: list[dict], models: list[dict], split: str) -> dict:
    r"""Whether the validation chose as the test would have, over the rows of ``tried`` with a validation gain and a
    figure on ``split``. Each row's test gain is measured as its validation gain is, against its own baseline: for
    ``rung N`` the ladder's model before it (``models[N - 1]``), for the probes and the hypotheses beside the
    diagnosis the final grey box (``models[-1]``), $1 - \text{figure} / \text{baseline's figure}$.
    ``agree``: the rows whose two gains have the same sign (both help, or both do not); ``rank_correlation``: the
    Spearman rank correlation of the two gains (+1: the validation orders the hypotheses as the test does);
    ``best_on_test``: the row with the lowest test figure (its stage, hypothesis, validation gain and figure)."""
    rows, validation_gains, test_gains = [], [], []
    for row in tried:
        if row["validation_gain"] is None or not row["rmse"] or row["rmse"].get(split) is None:
            continue
        before = models[int(row["stage"].split()[1]) - 1] if row["stage"].startswith("rung ") else models[-1]
        rows.append(row)
        validation_gains.append(row["validation_gain"])
        test_gains.append(1.0 - row["rmse"][split] / before["rmse"][split])
    if len(rows) < 3:
        return {"rank_correlation": None, "agree": None, "hypotheses": len(rows), "best_on_test": None}
    best = min(rows, key=lambda row: row["rmse"][split])
    return {"rank_correlation": float(spearmanr(validation_gains, test_gains)[0]),
            "agree": sum((v > 0) == (t > 0) for v, t in zip(validation_gains, test_gains, strict=True)),
            "hypotheses": len(rows),
            "best_on_test": {"stage": best["stage"] if best["place"] is None else f"probe: {best['place']}",
                             "hypothesis": best["hypothesis"], "validation_gain": best["validation_gain"],
                             split: best["rmse"][split]}}


def agreement_evidence(agreement: dict, split: str, unit: str) -> tuple[dict[str, float], str]:
    """:func:`validation_agreement`'s figures for a goal's ``evidence`` (``rank_correlation``, ``agree``,
    ``hypotheses``, ``best_on_test``, ``best_on_test_validation_gain``) and its sentence; none where too few
    hypotheses had both gains."""
    best = agreement["best_on_test"]
    if best is None:
        return {}, ""
    evidence = {"rank_correlation": agreement["rank_correlation"], "agree": agreement["agree"],
                "hypotheses": agreement["hypotheses"], "best_on_test": best[split],
                "best_on_test_validation_gain": best["validation_gain"]}
    return evidence, (f"over the {agreement['hypotheses']} hypotheses tried, the validation and the test agree on "
                      f"whether one helps for {agreement['agree']}, and the rank correlation of their gains is "
                      f"{agreement['rank_correlation']:+.2f} (+1: the validation orders them as the test does); the "
                      f"best on test, {best['hypothesis']} ({best['stage']}, {best[split]:.3g} {unit}), gains "
                      f"{100 * best['validation_gain']:.1f} % on validation")


def write_result(out: Path, result: dict, verdict: str) -> dict:
    """Write ``result`` as ``out/<benchmark>.json``, print the diagnosis' verdict and where it went; returns it."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{result['benchmark']}.json"
    path.write_text(json.dumps(result, indent=2))
    print(verdict)
    print(f"wrote {path} in {result['seconds']:.0f} s")
    return result
