"""The leaderboard's contract: what every benchmark experiment writes beside its own fields.

``DIR/<benchmark>.json`` holds::

    {"schema_version", "benchmark",
     "protocol": {"train", "test", "init_window", "metric", "unit"},
     "models": [{"model", "equation", "parameters", "uncertainty", "rmse": {<test split>: value}}],
     "hybrid": {"model", "accepted", "rmse": {<test split>: value or null}, "reason"},
     "goal": {"value", "split", "figure", "met", "limit": {"kind", "evidence", "explanation"}},
     "probes": [{"place", "fitted", "validation_gain", "rmse": {<test split>: value}, "kept", "note"}],
     "seconds"}

``models`` goes from the linear physics to the final grey box; ``hybrid`` is the final model with the orthogonal
residual of the paper on top (:func:`torchpaml.analysis.hybrid_residual`, fitted on the training records only), ``accepted``
where the final rung's alarm recommends it (neither inadequate nor complete physics), and an RMSE of ``null`` where a test input leaves the residual's domain.
``goal`` holds the benchmark's goal on its headline split (:func:`goal_entry`): the figure that counts (the hybrid's
where its alarm accepts it, else the final grey box's), whether it meets the goal, and what limits it: one of
:data:`LIMITS`, with the measured numbers that show it. ``probes`` holds the diagnosis' probes of where the final
grey box's mismatch points (:func:`probe_entries`): each place's extension, its validation gain, its test figure, and
whether it is kept (the place the probes name); empty where the final grey box is complete at the noise level.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path

import torch

from torchpaml import Adequacy, DomainError, MismatchProbes, ModelScore, Record, simulate_record
from torchpaml.analysis import hybrid_residual

__all__ = ["LIMITS", "SCHEMA_VERSION", "arguments", "goal_entry", "hybrid_entry", "model_entry", "probe_entries",
           "protocol", "write_result"]

#: The version of the leaderboard fields; a change of their meaning raises it.
SCHEMA_VERSION = 1
#: What may limit a figure: the measurement noise, the model class (a deterministic error the physics cannot
#: express), or data that do not determine a parameter (or the state a free run starts from).
LIMITS = ("noise floor", "model class", "data")


def arguments(doc: str, data: Path) -> argparse.ArgumentParser:
    """A benchmark run's command line: ``--out DIR``, ``--data PATH`` (default ``data``) and ``--shortlist K``."""
    parser = argparse.ArgumentParser(description=doc.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--data", type=Path, default=data, help=f"the benchmark's data folder (default {data})")
    parser.add_argument("--shortlist", type=int, default=2, help="candidates refitted per rung (default 2)")
    return parser


def protocol(train: str, test: list[str], init_window: int, metric: str, unit: str) -> dict:
    """The benchmark's protocol: the training and test splits, the samples that may set the initial state, the
    metric and its unit."""
    return {"train": train, "test": test, "init_window": init_window, "metric": metric, "unit": unit}


def model_entry(step: ModelScore, uncertainty: dict, rmse: dict[str, float]) -> dict:
    """One rung of the ladder as a leaderboard row (``uncertainty`` as ``diagnosis.json`` writes it)."""
    return {"model": step.name, "equation": step.equation, "parameters": step.parameters, "uncertainty": uncertainty,
            "rmse": rmse}


def hybrid_entry(step: ModelScore, train: list[Record], alpha: float, alarm: Adequacy,
                 tests: dict[str, tuple[Record, torch.Tensor | None]],
                 score: Callable[[Record, torch.Tensor], float]) -> dict:
    """The final model ``step`` plus the Chebyshev-Hammerstein residual fitted on its training residual, scored on
    each test record from its initial state by ``score(record, y_model)`` (the benchmark's metric over the scored
    samples); ``None`` where the test input leaves the residual's domain ``alpha``. ``accepted`` where the
    diagnosis' alarm on the final rung (``alarm``) recommends the hybrid: neither inadequate physics (the residual
    would hide it) nor complete physics (its residual is noise the orthogonal residual cannot reduce: the diagnosis
    says to use the physics alone, and a residual fitted to that noise scores by chance); ``reason``: its message."""
    accepted, reason = alarm.recommends_hybrid, alarm.message
    residual, _ = hybrid_residual(step, train, alpha)
    rmse = {}
    for name, (record, x0) in tests.items():
        with torch.no_grad():
            y = simulate_record(step.model, record, x0, solver=step.solver)[0]
            try:
                y = y + residual(record.elapsed, record.u[None])[0]
            except DomainError:
                rmse[name] = None
                continue
        rmse[name] = score(record, y)
    return {"model": f"{step.name} + ChebyshevHammerstein", "accepted": accepted, "rmse": rmse, "reason": reason}


def goal_entry(goal: float, split: str, models: list[dict], hybrid: dict, limit: str, evidence: dict[str, float],
               explanation: str) -> dict:
    """The goal on the headline ``split``: the figure that counts (the hybrid's where its alarm accepts it, else the
    final grey box's), whether it is at most ``goal``, and what limits it (one of :data:`LIMITS`; ``evidence``, the
    measured numbers that show it, in the benchmark's unit unless their name says otherwise)."""
    if limit not in LIMITS:
        raise ValueError(f"limit must be one of {LIMITS}, got {limit!r}")
    figure = hybrid["rmse"][split] if hybrid["accepted"] and hybrid["rmse"][split] is not None else \
        models[-1]["rmse"][split]
    return {"value": goal, "split": split, "figure": figure, "met": figure <= goal,
            "limit": {"kind": limit, "evidence": evidence, "explanation": explanation}}


def probe_entries(probes: MismatchProbes | None, test: Callable[[ModelScore], dict[str, float]]) -> list[dict]:
    """The probes' rows (:class:`torchpaml.MismatchProbes`) as leaderboard rows, each extended model scored on the
    test splits by ``test`` (the experiment's own metric); ``kept``: the place the probes name. The places were
    chosen on the validation records; the test figures are reported, not chosen on."""
    if probes is None:
        return []
    best = probes.best
    return [{"place": row.place, "fitted": row.fitted, "validation_gain": row.gain,
             "rmse": None if row.score is None else test(row.score), "kept": row is best, "note": row.note}
            for row in probes.rows]


def write_result(out: Path, result: dict, verdict: str) -> dict:
    """Write ``result`` as ``out/<benchmark>.json``, print the diagnosis' verdict and where it went; returns it."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{result['benchmark']}.json"
    path.write_text(json.dumps(result, indent=2))
    print(verdict)
    print(f"wrote {path} in {result['seconds']:.0f} s")
    return result
