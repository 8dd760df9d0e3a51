"""The ranking stage of a diagnosis: how each rung's candidate effects are ranked, as one frozen value."""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch

from torchpaml._budget import REFIT_BUDGET, RUNG_FIT_BUDGET, Budget, refit_evaluations
from torchpaml._data import Record
from torchpaml._diagnostics.ranking.beam import BEAM
from torchpaml._diagnostics.ranking.occam import KINDS, kind, simpler_alternatives, simpler_first
from torchpaml._diagnostics.ranking.steps import applicable, refit_shortlist, rung_fit, scored
from torchpaml._diagnostics.ranking.refits import Refits, free_shape
from torchpaml._diagnostics.ranking.scoring import as_records, score_model
from torchpaml._diagnostics.results import EffectEvidence, Ranking
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._errors import ConfigurationError
from torchpaml._fit.initial_state import InitialState, Rest, as_initial_state
from torchpaml._parameters import unphysical_values
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effects import AbstractEffect
from torchpaml._simulate.solvers import Solver
from torchpaml._fit.one_thread import one_thread

__all__ = ["Ranker", "rank_missing_effects"]

log = logging.getLogger("torchpaml._diagnostics.ranking.steps")

#: Refit criteria within this much of each other are the same evidence (a likelihood ratio within 1 %).
TIE = 0.01
#: First-order scores within this relative distance are the same first-order output (twins).
TWIN = 1e-6


def by_criterion(entries: list) -> list:
    """The refitted ``entries`` by their criterion, best first; those within :data:`TIE` of the best of their group
    in the order of ``entries`` (the candidates'). Equivalent candidates (an actuator and a sensor lag on linear
    physics give the same output) thus rank in the library's order, not by the last digits of two optimisations,
    and the same records give the same ranking on every machine."""
    place = {id(e): i for i, e in enumerate(entries)}
    ranked, group = [], []
    for entry in sorted((e for e in entries if e.refit is not None), key=lambda e: e.refit.criterion):
        if group and entry.refit.criterion > group[0].refit.criterion + TIE:
            ranked += sorted(group, key=lambda e: place[id(e)])
            group = []
        group.append(entry)
    return ranked + sorted(group, key=lambda e: place[id(e)])


@dataclass(frozen=True)
class Ranker:
    """How a diagnosis ranks every rung's candidate effects: the settings, and the ranking itself (:meth:`rank`).

    Attributes:
        rule: the decision rule (:class:`~torchpaml.SelectionRule`: BIC, threshold 10, min_share 5 %).
        shortlist: how many of the best-scored candidates are refitted.
        probe: strength $\\delta$ of the first-order secant.
        max_nfev: iteration limit of each refit.
        refit_budget: each refit may take this many times the evaluations of its rung's fit, and at least this many
            times ``max_nfev`` (:func:`~torchpaml._budget.refit_evaluations`).
        fit_budget: a rung's fit from the optimum of the refit that found its effect may take this many times that
            refit's evaluations; over it, the rung keeps the refit's parameters (``Ranking.fit_over_budget``).
        beam: how many models climb the ladder side by side, each rung's runner-ups on their own paths
            (:mod:`~torchpaml._diagnostics.ranking.beam`; 1: the greedy ladder).
    """

    rule: SelectionRule = field(default_factory=SelectionRule)
    shortlist: int = 2
    probe: float = 1e-4
    max_nfev: int = 100
    refit_budget: float = REFIT_BUDGET
    fit_budget: float = RUNG_FIT_BUDGET
    beam: int = BEAM

    def __post_init__(self):
        if isinstance(self.shortlist, bool) or not isinstance(self.shortlist, int) or self.shortlist < 1:
            raise ConfigurationError(f"shortlist must be at least 1 (how many best-scored candidates are refitted), "
                                     f"got {self.shortlist!r}")
        if isinstance(self.beam, bool) or not isinstance(self.beam, int) or self.beam < 1:
            raise ConfigurationError(f"beam must be at least 1 (how many models climb the ladder per rung; 1: the "
                                     f"greedy ladder), got {self.beam!r}")
        if not (isinstance(self.max_nfev, int) and self.max_nfev >= 1):
            raise ConfigurationError(f"max_nfev must be a whole number of evaluations, at least 1; got {self.max_nfev!r}")
        for name in ("probe", "refit_budget", "fit_budget"):
            value = getattr(self, name)
            if not (value > 0 and math.isfinite(value)):
                raise ConfigurationError(f"{name} must be positive and finite, got {value!r}")

    @one_thread()  # one arithmetic path (torchpaml._fit.one_thread)
    def rank(self, physics: AbstractPhysics, candidates: Sequence[AbstractEffect], train: Record | Sequence[Record],
             validation: Record | Sequence[Record], *, initial_state: InitialState = Rest(),
             start_states: Sequence[torch.Tensor] | None = None, deadline: float | None = None,
             solver: Solver | None = None, refitted: EffectEvidence | None = None) -> Ranking:
        """Rank ``candidates`` as the effect missing from ``physics`` (:mod:`~torchpaml._diagnostics.ranking.steps`).

        Args:
            physics: the physics to diagnose (not modified: a copy is fitted). Its learnable parameters
                are fitted; ``physics + effect`` must work for every candidate.
            candidates: effects at zero strength, e.g. :func:`~torchpaml.default_effects`; none: the
                fitted baseline alone.
            train: the records to fit on.
            validation: the records to rank on.
            initial_state: ``Rest()`` or ``Estimate()``: every fit estimates each training record's initial state
                (:func:`~torchpaml.fit_physics`), and each validation record starts from its best state
                (:mod:`~torchpaml._fit.initial_state`).
            start_states: with ``Estimate()``, the baseline fit's starting guesses of the training records' initial
                states (default rest).
            deadline: a ``time.perf_counter()`` time by which every fit must end (the diagnosis' ``budget``).
            solver: the solver ``physics`` was last fitted with (``PhysicsEstimate.solver``), or one to fit with,
                where the step checks of its fits start (``Auto(start=solver)``): a fixed-step method (RK4, TR-BDF2, a
                user's own) is the method of every refit and probe, also where the rung itself takes the exact path;
                default ``Auto()``.
            refitted: the refit that ``physics`` comes from (a ladder's next rung): the fit of ``physics`` may take
                ``fit_budget`` times that refit, and keeps the refit's parameters over it
                (``Ranking.fit_over_budget``). Without it, the fit runs to the ``deadline``.
        """
        train, validation = as_records(train), as_records(validation)
        initial_state, rule = as_initial_state(initial_state), self.rule
        candidates, skipped = applicable(physics, candidates)
        end = math.inf if deadline is None else deadline
        base, fit, seconds, over = rung_fit(physics, train, self.max_nfev, initial_state, start_states, solver,
                                            refitted, self.fit_budget, end)
        baseline = score_model(base, fit, validation, rule, initial_state)
        # the rung's fit in evaluations: its refit's and its own (the same count on every machine)
        made = fit.evaluations + (0 if refitted is None or over is not None else refitted.refit.estimate.evaluations)
        limits = Budget(base.display_name, evaluations=refit_evaluations(self.refit_budget, made, self.max_nfev),
                        deadline=end)
        if not candidates:
            return Ranking(baseline, [], rule, skipped, initial_state, over, seconds)
        if solver is not None and fit.solver.stepping() is None:  # a rung on the exact path: effects step by solver
            fit = dataclasses.replace(fit, solver=solver)
        log.info("scoring %d candidates to first order", len(candidates))
        entries, extended_models = scored(base, candidates, train, fit, self.probe)
        by_score = sorted(entries, key=lambda e: -e.score)
        refits = Refits(base.display_name, train, validation, fit, baseline, rule, initial_state, self.max_nfev, limits)
        refit_shortlist([e for e in by_score if e.effect in extended_models], extended_models, self.shortlist, rule,
                        validation, base, refits)
        weigh_beyond_the_shortlist(entries, by_score, extended_models, baseline, rule, refits)
        refitted = by_criterion(entries)
        if refitted:  # the best may ask for another shape (freeing only improves it, so it stays first)
            best = refitted[0]
            free_shape(best, train, validation, rule, self.max_nfev, initial_state, refits.budget(best.effect))
            best.improvement = baseline.criterion - best.refit.criterion
            best.unphysical = unphysical_values(best.refit.rows())
        rest = [e for e in by_score if e.refit is None]
        ordered, simpler = simpler_first(refitted + rest, baseline, rule)
        return Ranking(baseline, ordered, rule, skipped, initial_state, over, seconds, simpler, equivalents(ordered))


def weigh_beyond_the_shortlist(entries: list[EffectEvidence], by_score: list[EffectEvidence], extended_models: dict,
                               baseline, rule: SelectionRule, refits: Refits) -> None:
    """Refit what the decision must weigh beyond the shortlist: the best-scored candidate of each simpler kind
    (:func:`~torchpaml._diagnostics.ranking.occam.simpler_alternatives`), then the **twins** of the leading
    candidate, those whose first-order score equals its own to :data:`TWIN` (the same first-order output: an
    actuator and a sensor lag on linear physics), for :func:`equivalents` to say whether they are the same."""
    def in_order() -> list[EffectEvidence]:
        return [e for e in by_criterion(entries) + [e for e in by_score if e.refit is None] if e.effect in extended_models]

    for entry in simpler_alternatives(in_order(), baseline, rule):
        entry.refit_reason = (f"refitted: the best-scored candidate {KINDS[kind(entry)]}, for the simpler-effect "
                              f"rule to weigh against the more complex one the rule accepts")
        refits.run(entry, *extended_models[entry.effect])
    lead = simpler_first(in_order(), baseline, rule)[0][0] if in_order() else None
    if lead is None or lead.refit is None:
        return
    for entry in (e for e in in_order() if e.refit is None and e.failure is None and e.undecided is None):
        if math.isclose(entry.score, lead.score, rel_tol=TWIN):
            entry.refit_reason = (f"refitted: its first-order score equals {lead.effect}'s (the same first-order "
                                  "output), for the ranking to say whether the two are the same")
            refits.run(entry, *extended_models[entry.effect])


def equivalents(ordered: list[EffectEvidence]) -> list[str]:
    """The refitted candidates whose criterion is within :data:`TIE` of the first's: the same evidence, so the
    records cannot tell them from it (they rank in the library's order, :func:`by_criterion`)."""
    lead = ordered[0] if ordered and ordered[0].refit is not None else None
    return [] if lead is None else [e.effect for e in ordered[1:] if e.refit is not None and not e.unphysical
                                    and abs(e.refit.criterion - lead.refit.criterion) <= TIE]


def rank_missing_effects(
    physics: AbstractPhysics,
    candidates: Sequence[AbstractEffect],
    train: Record | Sequence[Record],
    validation: Record | Sequence[Record],
    *,
    rule: SelectionRule | None = None,
    shortlist: int = 2,
    probe: float = 1e-4,
    max_nfev: int = 100,
    refit_budget: float = REFIT_BUDGET,
    fit_budget: float = RUNG_FIT_BUDGET,
    **options,
) -> Ranking:
    """``Ranker(rule, shortlist, probe, max_nfev, refit_budget, fit_budget).rank(physics, candidates, train,
    validation, **options)``: the ranking in one call (:meth:`Ranker.rank`)."""
    return Ranker(rule or SelectionRule(), shortlist, probe, max_nfev, refit_budget, fit_budget).rank(
        physics, candidates, train, validation, **options)
