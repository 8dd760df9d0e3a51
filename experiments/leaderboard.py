"""The leaderboard's contract: what every benchmark experiment writes beside its own fields.

``DIR/<benchmark>.json`` holds::

    {"schema_version", "benchmark",
     "protocol": {"train", "test", "init_window", "metric", "unit"},
     "models": [{"model", "equation", "parameters", "uncertainty", "rmse": {<test split>: value}}],
     "hybrid": {"model", "accepted", "rmse": {<test split>: value or null}, "reason"},
     "seconds"}

``models`` goes from the linear physics to the final grey box; ``hybrid`` is the final model with the orthogonal
residual of the paper on top (:func:`torchpaml.hybrid_residual`, fitted on the training records only), ``accepted``
from its inadequacy alarm on validation, and an RMSE of ``null`` where a test input leaves the residual's domain.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

from torchpaml import DomainError, ModelScore, Record, hybrid_residual, simulate_record

__all__ = ["SCHEMA_VERSION", "hybrid_entry", "model_entry", "protocol"]

#: The version of the leaderboard fields; a change of their meaning raises it.
SCHEMA_VERSION = 1


def protocol(train: str, test: list[str], init_window: int, metric: str, unit: str) -> dict:
    """The benchmark's protocol: the training and test splits, the samples that may set the initial state, the
    metric and its unit."""
    return {"train": train, "test": test, "init_window": init_window, "metric": metric, "unit": unit}


def model_entry(step: ModelScore, uncertainty: dict, rmse: dict[str, float]) -> dict:
    """One rung of the ladder as a leaderboard row (``uncertainty`` as ``diagnosis.json`` writes it)."""
    return {"model": step.name, "equation": step.equation, "parameters": step.parameters, "uncertainty": uncertainty,
            "rmse": rmse}


def hybrid_entry(step: ModelScore, train: list[Record], alpha: float, accepted: bool, reason: str,
                 tests: dict[str, tuple[Record, torch.Tensor | None]],
                 score: Callable[[Record, torch.Tensor], float]) -> dict:
    """The final model ``step`` plus the Chebyshev-Hammerstein residual fitted on its training residual, scored on
    each test record from its initial state by ``score(record, y_model)`` (the benchmark's metric over the scored
    samples); ``None`` where the test input leaves the residual's domain ``alpha``."""
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
