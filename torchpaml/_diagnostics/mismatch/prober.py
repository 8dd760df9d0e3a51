r"""The probe stage of a diagnosis: where the mismatch of the ladder's last rung points.

Where no library candidate passes the rule and the model is not complete at the noise level, each place of
:mod:`~torchpaml._diagnostics.mismatch.places` is probed on the last rung: of the library effects that extend the
physics there (and apply to it), the ``shortlist`` ones with the highest first-order scores are refitted with the physics on the
training records and scored on validation, as the ranking refits its shortlist (:class:`~torchpaml.Ranker`: its
probe strength, iteration limit and refit budget); an effect the ranking refitted already is taken from its ranking.
The force's place also takes the discovery's closed form where the discovery ran (a diagnosis probes before it
discovers, and adds the form afterwards: :meth:`~torchpaml._diagnostics.mismatch.result.MismatchProbes.with_discovery`), and the output map's place the
closed form of the output's residual over the states and inputs
(:func:`~torchpaml._diagnostics.discovery.output_map.output_closed_form`); the initial state's place estimates
each validation record's initial state on its start window (:func:`~torchpaml._fit.initial_state.start_window`)
and measures the gain on the rest, which that fit did not see (as every other probe's gain is measured on
validation records its fit did not see), and says where in time the error sits (:mod:`~torchpaml._diagnostics.mismatch.in_time`). An effect with a ``far_strength``
(:attr:`~torchpaml.AbstractEffect.far_strength`, e.g. a sensor that reads only the magnitude) is also refitted from
it on the first rung's physics, without the effects the ladder fitted in its place, and on the physics as the user
started it: a linear fit of a magnitude-only output is degenerate (no damping, a gain near zero), and a refit from
there stays in its valley (73 % on training where the user's start reaches the 2 % noise). Each place's *validation
gain* is the share by which its extension lowers the model's validation mismatch; the table names the place with the
largest gain (:class:`~torchpaml._diagnostics.mismatch.result.MismatchProbes`).
"""

from __future__ import annotations

import copy
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from torchpaml._budget import Budget, OverBudget, refit_evaluations
from torchpaml._data import Record
from torchpaml._diagnostics.discovery.result import Discovery
from torchpaml._diagnostics.mismatch.in_time import error_in_time
from torchpaml._diagnostics.discovery.output_map import NAME as CLOSED_FORM
from torchpaml._diagnostics.discovery.output_map import output_closed_form
from torchpaml._diagnostics.mismatch.places import FORCE, INITIAL_STATE, OUTPUT_MAP, PLACES, Place
from torchpaml._diagnostics.mismatch.result import DISCOVERED, MismatchProbes, ProbeResult, ranked
from torchpaml._diagnostics.ranking.first_order import MIN_ACTING_SHARE
from torchpaml._diagnostics.ranking.ranker import Ranker
from torchpaml._diagnostics.ranking.refits import Refits, effect_bounds
from torchpaml._diagnostics.ranking.scoring import as_records, score_model, scored_mismatch
from torchpaml._diagnostics.ranking.steps import applicable, placed, scored
from torchpaml._diagnostics.results import EffectEvidence, ModelScore, Ranking
from torchpaml._errors import ConfigurationError, ResolutionError, SimulationError
from torchpaml._fit.initial_state import START_WINDOW, Estimate
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effects import EFFECTS
from torchpaml._fit.one_thread import one_thread

__all__ = ["Prober"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Prober:
    """The settings of the probe stage (module docstring), and the probing itself (:meth:`probe`).

    Attributes:
        places: the places probed (:data:`~torchpaml._diagnostics.mismatch.places.PLACES`), each naming library
            effects.
        always: probe also where the last rung is complete at the noise level (by default the table then says so).
    """

    places: tuple[Place, ...] = PLACES
    always: bool = False

    def __post_init__(self):
        unknown = sorted({name for place in self.places for name in place.effects} - set(EFFECTS))
        if unknown:
            raise ConfigurationError(f"the probes' places name effects outside the library: {unknown}; choose from "
                                     f"{sorted(EFFECTS)}")

    @one_thread()  # one arithmetic path (torchpaml._fit.one_thread)
    def probe(self, ranking: Ranking, train: Record | Sequence[Record], validation: Record | Sequence[Record], *,
              ranker: Ranker = Ranker(), deadline: float | None = None, discovery: Discovery | None = None,
              complete: bool = False, first: ModelScore | None = None, discovering: bool = False,
              start: AbstractPhysics | None = None) -> MismatchProbes:
        """Probe every place on ``ranking``'s baseline (the ladder's last rung), fitted on ``train`` and scored on
        ``validation``. ``ranker``: the ranking's settings, which the refits use; ``deadline``: a
        ``time.perf_counter()`` time by which every refit ends (a refit over it is reported undecided);
        ``discovery``: the discovery on that rung, whose closed form the force's place takes (a diagnosis probes
        first and adds it afterwards, :meth:`MismatchProbes.with_discovery`); ``discovering``: a discovery follows
        (the force's place then does not suggest one); ``complete``: the
        rung's residual is noise (no probe runs unless :attr:`always`); ``first``: the ladder's first rung, the
        physics fitted alone, from which an effect's ``far_strength`` is refitted (default: ``ranking``'s
        baseline); ``start``: the physics as the user started it, before any fit, from which it is refitted too."""
        train, validation = as_records(train), as_records(validation)
        score = ranking.baseline
        model, fit = score.model, score.estimate
        probes = MismatchProbes(model.display_name, score.nrmse_validation, places=tuple(p.name for p in self.places),
                                in_time=error_in_time(validation, score.validation_outputs),
                                min_gain=ranking.rule.min_share)
        if complete and not self.always:
            probes.reason = "its residual is noise that the orthogonal residual cannot reduce: complete at this noise level"
            return probes
        end = math.inf if deadline is None else deadline
        if time.perf_counter() >= end:
            probes.reason = "the diagnosis' budget was spent before the probes"
            return probes
        log.info("probing where the mismatch of %s points: %d places", model.display_name, len(self.places))
        effects = {place.name: self._usable(place, model) for place in self.places}
        refitted = {e.effect: e for e in ranking.entries if e.refit is not None}
        fresh = [effect for usable in effects.values() for effect in usable if effect.name not in refitted]
        entries, extended = scored(model, fresh, train, fit, ranker.probe) if fresh else ([], {})
        new = {e.effect: e for e in entries}
        template = Budget(model.display_name, evaluations=refit_evaluations(ranker.refit_budget, fit.evaluations,
                                                                     ranker.max_nfev), deadline=end)
        refits = Refits(model.display_name, train, validation, fit, score, ranking.rule, ranking.initial_state,
                        ranker.max_nfev, template)
        rows = []
        for place in self.places:
            if place.name == INITIAL_STATE:
                rows.append(self._initial_state(place, ranking, validation, probes))
                continue
            names = [effect.name for effect in effects[place.name]]
            tried = [refitted[name] for name in names if name in refitted]
            if not tried:
                tried = _refit_best([new[name] for name in names if name in new], extended, refits, ranker.shortlist)
            extras = _discovered(discovery) if place.name == FORCE else \
                self._output_form(ranking, train, validation, ranker, template) if place.name == OUTPUT_MAP else []
            extras += _from_far_strength(effects[place.name], first or score, start, ranking, train, validation,
                                         ranker, template)
            rows.append(_row(place, tried, score.nrmse_validation, extras,
                             discovered=discovery is not None or discovering))
        probes.rows = ranked(rows, list(probes.places))
        return probes

    @staticmethod
    def _usable(place: Place, model) -> list:
        """The place's library effects that apply to ``model`` and are not in it, each force on every degree of
        freedom it may act on."""
        present = set(model.effect_names())
        effects = [e for e in placed(model, [EFFECTS[name]() for name in place.effects]) if e.name not in present]
        if not effects:
            return []
        try:
            return applicable(model, effects)[0]
        except ConfigurationError:  # none of them applies
            return []

    @staticmethod
    def _output_form(ranking: Ranking, train: list[Record], validation: list[Record], ranker: Ranker,
                     template: Budget) -> list[tuple]:
        """The closed form of the output map's residual (:func:`~torchpaml._diagnostics.discovery.output_map.output_closed_form`),
        as an option of the output map's place; none where the regression keeps no term or its refit fails."""
        try:
            found = output_closed_form(ranking.baseline, train, validation, ranking.rule, ranking.initial_state,
                                       max_nfev=ranker.max_nfev, budget=template.restarted("the output map's closed form"))
        except (OverBudget, ResolutionError, SimulationError) as error:
            log.info("output map: no closed form (%s)", error)
            return []
        if found is None:
            return []
        form = found.model.effects[CLOSED_FORM].expression()
        return [(found, f"y + {form}".replace("+ -", "- "), "the closed form of the output map's residual (a regression on the "
                                       "discovery's terms, refitted)")]

    @staticmethod
    def _initial_state(place: Place, ranking: Ranking, validation: list[Record], probes: MismatchProbes
                       ) -> ProbeResult:
        """The model scored with each validation record's initial state estimated, and where in time its error sits."""
        where = probes.in_time.describe()
        if isinstance(ranking.initial_state, Estimate):
            return ProbeResult(place.name, place.extension, note=f"estimated already (--initial_state estimate); {where}")
        score = ranking.baseline
        estimated = score_model(score.model, score.estimate, validation, ranking.rule, Estimate())
        gain = held_out_gain(score, estimated, validation)
        note = (f"{where}; each validation record's state estimated on its first {100 * START_WINDOW:g} % and the "
                f"gain measured on the rest, which that fit did not see")
        return ProbeResult(place.name, place.extension, INITIAL_STATE, estimated.nrmse_validation, gain, note,
                           estimated)


def held_out_gain(rest: ModelScore, estimated: ModelScore, validation: list[Record]) -> float:
    """The gain of ``estimated`` (the model scored with ``Estimate()``: each validation record's state estimated on
    its start window, the mismatch over the samples after it) against ``rest`` (the same model from rest) on the
    same samples: $1 - m_\\text{estimated} / m_\\text{rest}$."""
    return 1.0 - estimated.nrmse_validation / scored_mismatch(validation, rest.validation_outputs, Estimate())


def _refit_best(entries: list[EffectEvidence], extended: dict[str, tuple], refits: Refits, shortlist: int
                ) -> list[EffectEvidence]:
    """Refit the ``shortlist`` entries of ``entries`` with the highest first-order scores (of those whose probe acts
    on enough samples to be scored); the entries refitted."""
    scorable = [e for e in entries if e.effect in extended and e.acting >= MIN_ACTING_SHARE]
    best = sorted(scorable, key=lambda e: -e.score)[:shortlist]
    for entry in best:
        entry.refit_reason = "refitted: among the best first-order scores of its place"
        refits.run(entry, *extended[entry.effect])
    return best


def _from_far_strength(effects: list, first: ModelScore, start: AbstractPhysics | None, ranking: Ranking,
                       train: list[Record], validation: list[Record], ranker: Ranker, template: Budget) -> list[tuple]:
    """Each of ``effects`` that has a ``far_strength``, refitted from it on ``first``'s physics and on ``start`` (the
    physics as the user started it; skipped where ``None``), each as a shortlisted refit within its budget, and scored
    on validation: options of its place (``(score, fitted, note)``)."""
    options = []
    refits = Refits(first.model.display_name, train, validation, first.estimate, first, ranking.rule,
                    ranking.initial_state, ranker.max_nfev, template)
    bases = [(first.model, "alone")] + ([] if start is None else [(start, "as started")])
    for effect in (e for e in effects if e.far_strength is not None):
        for base, how in bases:
            entry = EffectEvidence(effect.name, effect.equation, 0.0, 1, effect.far_strength,
                                   refit_reason=f"refitted from its far strength on the physics {how}")
            extended = copy.deepcopy(base) + copy.deepcopy(effect)
            refits.run(entry, extended, f"{effect.name}.{effect.strength}", None, effect_bounds(extended, train))
            if entry.refit is None:
                log.info("%s from %s = %g on %s %s: no refit (%s)", effect.name, effect.strength, effect.far_strength,
                         base.display_name, how, entry.failure or entry.refit_reason)
                continue
            own = _parameters(entry).rsplit(" (", 1)[0]
            options.append((entry.refit, effect.name, f"{own} (refitted from {effect.strength} = "
                                                      f"{effect.far_strength:g} on {base.display_name} {how})"))
    return options


def _discovered(discovery: Discovery | None) -> list[tuple]:
    """The discovery's closed form, as an option of the force's place; none where it found none."""
    if discovery is None or discovery.discovered is None:
        return []
    return [(discovery.discovered, discovery.text, DISCOVERED)]


def _row(place: Place, tried: list[EffectEvidence], validation: float, extras: list[tuple],
         discovered: bool) -> ProbeResult:
    """The place's row: the best of its refitted effects and of ``extras`` (``(score, fitted, note)``: the discovery's
    closed form for the force, the output map's for the output map)."""
    options = [(e.refit, e.effect, _parameters(e)) for e in tried if e.refit is not None] + extras
    if not options:
        why = "; ".join(f"{e.effect}: {e.failure or e.refit_reason}" for e in tried) or \
            "no library effect of this place applies"
        if place.name == FORCE and not discovered:
            why += "; the discovery (--discover) learns a force of any form"
        return ProbeResult(place.name, place.extension, note=why)
    best, name, note = min(options, key=lambda option: option[0].nrmse_validation)
    return ProbeResult(place.name, place.extension, name, best.nrmse_validation,
                       1.0 - best.nrmse_validation / validation, note, best)


def _parameters(entry: EffectEvidence) -> str:
    """The refitted effect's own parameters, ``name = value`` (with its first-order score)."""
    own = ", ".join(f"{key.split('.', 1)[1]} = {value:.4g}" for key, value in entry.refit.parameters.items()
                    if key.startswith(f"{entry.effect}."))
    return f"{own} (first-order score {entry.score:.3g})"
