"""The ranking stage of a diagnosis: how each rung's candidate effects are ranked, as one frozen value."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch

from torchpaml._budget import REFIT_BUDGET, RUNG_FIT_BUDGET
from torchpaml._data import Record
from torchpaml._diagnostics.ranking import rank_missing_effects
from torchpaml._diagnostics.results import EffectEvidence, Ranking
from torchpaml._diagnostics.selection import SelectionRule
from torchpaml._errors import ConfigurationError
from torchpaml._fit.initial_state import InitialState, Rest
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effects import AbstractEffect
from torchpaml._simulate.solvers import Solver

__all__ = ["Ranker"]


@dataclass(frozen=True)
class Ranker:
    """The settings of :func:`~torchpaml.rank_missing_effects` that a diagnosis ranks every rung by.

    Attributes:
        rule: the decision rule (:class:`~torchpaml.SelectionRule`: BIC, threshold 10, min_share 5 %).
        shortlist: how many of the best-scored candidates are refitted.
        probe: strength $\\delta$ of the first-order secant.
        max_nfev: iteration limit of each refit.
        refit_budget: each refit may take this many times its rung's fit, in seconds or in its fit's evaluations at
            the refit's own cost, whichever is longer (:mod:`torchpaml._budget`).
        fit_budget: a rung's fit from the optimum of the refit that found its effect may take this many times that
            refit; over it, the rung keeps the refit's parameters (``Ranking.fit_over_budget``).
    """

    rule: SelectionRule = field(default_factory=SelectionRule)
    shortlist: int = 2
    probe: float = 1e-4
    max_nfev: int = 40
    refit_budget: float = REFIT_BUDGET
    fit_budget: float = RUNG_FIT_BUDGET

    def __post_init__(self):
        if isinstance(self.shortlist, bool) or not isinstance(self.shortlist, int) or self.shortlist < 1:
            raise ConfigurationError(f"shortlist must be at least 1 (how many best-scored candidates are refitted), "
                                     f"got {self.shortlist!r}")
        if not (isinstance(self.max_nfev, int) and self.max_nfev >= 1):
            raise ConfigurationError(f"max_nfev must be a whole number of evaluations, at least 1; got {self.max_nfev!r}")
        for name in ("probe", "refit_budget", "fit_budget"):
            value = getattr(self, name)
            if not (value > 0 and math.isfinite(value)):
                raise ConfigurationError(f"{name} must be positive and finite, got {value!r}")

    def rank(self, physics: AbstractPhysics, candidates: Sequence[AbstractEffect], train: Sequence[Record],
             validation: Sequence[Record], *, initial_state: InitialState = Rest(),
             start_states: Sequence[torch.Tensor] | None = None, deadline: float | None = None,
             solver: Solver | None = None, refitted: EffectEvidence | None = None) -> Ranking:
        """:func:`~torchpaml.rank_missing_effects` with these settings."""
        return rank_missing_effects(physics, candidates, train, validation, rule=self.rule, shortlist=self.shortlist,
                                    initial_state=initial_state, start_states=start_states, probe=self.probe,
                                    max_nfev=self.max_nfev, refit_budget=self.refit_budget,
                                    fit_budget=self.fit_budget, deadline=deadline,
                                    solver=solver, refitted=refitted)
