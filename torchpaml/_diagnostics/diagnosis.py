r"""The whole diagnosis: compare, where it fails, which effect is missing, add it, the residual on top.

:func:`diagnose` runs, on training and validation records:

1. the **model ladder** (:func:`~torchpaml.model_ladder`): the physics fitted, the
   candidates ranked by the ``ranker`` (:class:`~torchpaml.Ranker`), the best added while it
   beats the current model's criterion by more than the threshold;
2. **where the fitted physics fails** on the validation records: residual whiteness and input
   cross-correlation (:func:`~torchpaml.residual_analysis`), and the mismatch binned by
   |u| and by |y| (:func:`~torchpaml.error_by_amplitude`), for each output channel, with each channel's mismatch
   before and after the ladder and the channel where the missing effect shows most
   (:mod:`~torchpaml._diagnostics.analysis.channels`);
3. the **Chebyshev-Hammerstein residual** fitted on top of the first and of the last rung, with the
   inadequacy alarm (:func:`~torchpaml.assess_adequacy`): on wrong physics it cannot
   close the gap and says so; on physics whose training residual is noise by effect size (its
   cross-correlation with the input below :data:`NOISE_CORRELATION` at all but :data:`WHITE_SHARE`
   of the lags, coloured or not, whatever the record's length, and the orthogonal residual unable to
   reduce it: :data:`~torchpaml._diagnostics.analysis.adequacy.NOISE_RATIO`) and whose validation mismatch is within
   :data:`~torchpaml._diagnostics.analysis.adequacy.FLOOR_FACTOR` times the noise floor read from the records
   (:mod:`~torchpaml._diagnostics.analysis.noise_floor`), it says that the physics is
   complete at that noise level. The two residual fits are independent and run in two threads where torch has two
   or more (their filtering, in scipy and torch, releases the GIL: 36 s -> 27 s at 100 000 samples, the same
   numbers), in one where it has one (a fleet's worker, whose share of the cores is one);
4. the **probes of where the mismatch points** (:class:`~torchpaml.Prober`), where the last rung is not complete at
   the noise level: one small, interpretable extension refitted at each place the missing physics may sit (the
   actuator's and the sensor's dynamics, one more mode, the static maps of the output and of the input, a force, a
   latent state, the initial state), each scored by its validation gain, the best named in the verdict. They are
   the cheap questions, so they run first, within the budget;
5. with ``discovery=Discoverer()``, the **discovery** of a force or rate outside the library on the ladder's
   last rung (:func:`~torchpaml.discover_missing_force`: a neural rate in the ODE, then its
   closed form, ranked against the library's best remaining effect), so that it can find a second
   effect on top of a first. It is asked for, not automatic: it trains a
   network through the simulator, so its cost grows with the record's length; it gets what is left of the budget
   (a progress line says how much), and its closed form then joins the probes' force place. Where the ladder added
   effects and the last rung's discovery recommends nothing (or, complete, did not search), the discovery also runs
   on the physics alone (:func:`_against_stand_ins`): its form replaces the ladder's effects where the rule
   recommends it there, the last rung does not beat it by the rule, and it has fewer fitted parameters; the effects
   stood in for it (``Discovery.replaces``), and :attr:`Diagnosis.final` is the form.

**One arithmetic path.** The whole diagnosis runs with torch's and the BLAS pools at one thread
(:mod:`~torchpaml._fit.one_thread`), not only its fits: a first-order score, a start or a validation score summed
over two threads is added in another order than over one, and a ladder's rung fit that starts from it can end in
another optimum. The two residual fits still run side by side, each on one thread.
"""

from __future__ import annotations

import logging
import math
import time
import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import torch

from torchpaml._data import Record
from torchpaml._diagnostics.analysis.adequacy import Adequacy, assess_adequacy
from torchpaml._diagnostics.analysis.channels import ChannelScore, channel_scores, shows_most
from torchpaml._diagnostics.analysis.noise_floor import noise_floor
from torchpaml._diagnostics.discovery.closed_form import fit_closed_form
from torchpaml._diagnostics.discovery.discoverer import Discoverer
from torchpaml._diagnostics.discovery.result import Discovery
from torchpaml._diagnostics.mismatch.prober import Prober
from torchpaml._diagnostics.mismatch.result import MismatchProbes
from torchpaml._diagnostics.ranking.ladder import Ladder, model_ladder
from torchpaml._diagnostics.ranking.ranker import TIE, Ranker
from torchpaml._diagnostics.results import ModelScore, Ranking
from torchpaml._diagnostics.ranking.scoring import as_records, score_model, scored_mismatch
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._budget import DEFAULT_BUDGET, REFIT_BUDGET, RUNG_FIT_BUDGET, Budget, OverBudget, check_budget
from torchpaml._diagnostics.analysis.residuals import ResidualAnalysis, residual_analysis
from torchpaml._diagnostics.analysis.validity import AmplitudeBins
from torchpaml._errors import ConfigurationError, DataError, SimulationError
from torchpaml._grid import uniform_step
from torchpaml._data.simulation import simulate_record
from torchpaml._fit.residual_fit import fit_chebyshev_hammerstein, joined_in_time, per_record
from torchpaml._metrics import mismatch
from torchpaml._parameters import describe_parameters
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._fit.initial_state import InitialState, Rest, as_initial_state
from torchpaml._fit.one_thread import one_thread
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.checks import check_channels, check_physics, check_time_scale
from torchpaml._data.checks import check_outputs_vary, check_scales_agree
from torchpaml._physics.effects import AbstractEffect
from torchpaml._physics.terms import TermLibrary
from torchpaml._residual.chebyshev_hammerstein import ChebyshevHammerstein

__all__ = ["Diagnosis", "HybridScore", "diagnose", "hybrid_residual"]

log = logging.getLogger(__name__)

#: A residual counts as noise when at most this share of its input cross-correlation lags exceed
#: :data:`NOISE_CORRELATION` and the 99 % bound (5 % leaves room for a few; a missing effect exceeds most).
WHITE_SHARE = 0.05
#: The effect size below which an input cross-correlation is noise, whatever the record's length: the input
#: then explains under 1 % of the residual's variance at that lag. A p-value alone would call any
#: correlation significant on a long enough record, and coloured sensor noise is not a missing effect.
NOISE_CORRELATION = 0.1
#: The residual fits' stopping tolerance (``rtol`` of :func:`~torchpaml.fit_chebyshev_hammerstein`): the
#: verdict needs the hybrid's mismatch to a few digits, not the last ones. Measured on the demo system at 20 000 and
#: 100 000 samples against the fit's default (1e-9): where the residual has structure (the linear oscillator's), the
#: unexplained share agrees to eight digits; where it is noise (the complete model), the fit stops after one step,
#: 1e-4 of the share short of the noise it would go on to fit, in 1.3 s instead of 27 s at 100 000 samples.
DECISION_TOLERANCE = 1e-7


@dataclass
class HybridScore:
    """A physics model with the Chebyshev residual on top: mismatches (fractions) and the adequacy verdict."""

    model: str
    physics_train: float
    hybrid_train: float
    physics_validation: float
    hybrid_validation: float
    adequacy: Adequacy
    #: the fitted Chebyshev-Hammerstein residual
    residual: ChebyshevHammerstein | None = field(default=None, repr=False)


@dataclass
class Diagnosis:
    """Everything :func:`diagnose` found (module docstring).

    :func:`~torchpaml.diagnosis_to_dict` turns it into the ``diagnosis.json`` content,
    :func:`~torchpaml.diagnosis_figures` into figures, and :func:`~torchpaml.write_report` writes both.
    """

    ladder: Ladder
    residuals: ResidualAnalysis
    by_input: AmplitudeBins
    by_output: AmplitudeBins
    hybrids: list[HybridScore]
    validation: list[Record] = field(repr=False)
    discovery: Discovery | None = None
    #: each output channel on validation (:mod:`~torchpaml._diagnostics.analysis.channels`); ``residuals``, ``by_input`` and
    #: ``by_output`` are the first channel's
    channels: list[ChannelScore] = field(default_factory=list)
    #: where the last rung's mismatch points (:class:`~torchpaml.Prober`); ``None`` where the probes were not asked for
    probes: MismatchProbes | None = None

    @property
    def shows_most(self) -> ChannelScore:
        """The output channel where the effects the ladder added lowered the mismatch most (where it added none: where
        the physics fails most)."""
        return shows_most(self.channels, bool(self.ladder.added))

    @property
    def final(self) -> ModelScore:
        """The model the diagnosis ends with: the discovery's closed form where it recommends it, else the ladder's
        last rung."""
        found = self.discovery
        return found.discovered if found is not None and found.recommended and found.discovered else self.ladder.final

    @property
    def model(self) -> FittedModel:
        """:attr:`final` as one value to save, load and run (:func:`~torchpaml.save_model`): with its solver, the
        validation records' channels and hold, the initial-state policy and the fit's uncertainty."""
        return self._fitted(self.final)

    @property
    def hybrid(self) -> FittedModel | None:
        """The ladder's last rung with the Chebyshev residual on top where its alarm recommends the hybrid
        (:attr:`~torchpaml.Adequacy.recommends_hybrid`), else ``None``."""
        last = self.hybrids[-1]
        if not last.adequacy.recommends_hybrid or last.residual is None:
            return None
        return self._fitted(self.ladder.final, last.residual)

    def _fitted(self, score: ModelScore, residual: ChebyshevHammerstein | None = None) -> FittedModel:
        record = self.validation[0]
        return FittedModel(score.model, score.solver, residual, tuple(record.input_names),
                           tuple(record.output_names), record.hold, self.ladder.rankings[-1].initial_state,
                           None if score.estimate is None else score.estimate.uncertainty, _uniform_step(record),
                           _residual_rms(self.validation, score.validation_outputs))

    @property
    def baseline(self) -> ModelScore:
        return self.ladder.steps[0]

    @property
    def ranking(self) -> Ranking:
        return self.ladder.rankings[0]

    @property
    def compared_models(self) -> list[ModelScore]:
        """The fitted physics and, where the ladder added effects, the final model."""
        return _distinct(self.baseline, self.ladder.final)

    @property
    def _removed(self) -> str:
        """The effects the ladder added and then removed as stand-ins, as a clause of the verdict ("" where none)."""
        gone = [r.effect for r in self.ladder.removals if r.removed]
        return "" if not gone else (f" ({', '.join(gone)} added, then removed: the later effects explain what "
                                    f"{'it' if len(gone) == 1 else 'they'} stood in for)")

    @property
    def _beam(self) -> str:
        """Where the beam chose another path than the greedy one, as a clause of the verdict ("" where it did not)."""
        greedy = next((end for end in self.ladder.beam if end.greedy), None)
        if greedy is None or greedy.chosen:
            return ""
        return (f" (the greedy path ends at {' + '.join(greedy.effects)}, {100 * greedy.nrmse_validation:.2f} % on "
                f"validation; this path, through a runner-up, beats it by the rule)")

    @property
    def verdict(self) -> str:
        """One paragraph: what is missing, how the error fell, and what the residual on top says."""
        base, final = self.baseline, self.ladder.final
        if self.ladder.added:
            replaced = self.discovery is not None and bool(self.discovery.replaces)
            found = (f"missing effect(s) found: {', '.join(self.ladder.found)}{self._removed}{self._beam}. "
                     f"Validation mismatch {100 * base.nrmse_validation:.2f} % -> {100 * final.nrmse_validation:.2f} %. "
                     f"{'Last rung' if replaced else 'Final model'}: {final.equation}.")
        else:
            best = next((e for e in self.ranking.entries if e.improvement is not None), None)
            detail = "" if best is None else (
                f" (the best, {best.effect}, improves {self.ranking.rule.criterion.upper()} by {best.improvement:.1f} and "
                f"the validation mismatch by {100 * (1 - best.refit.nrmse_validation / base.nrmse_validation):.1f} %; "
                f"needed: {self.ranking.rule.threshold:g} and {100 * self.ranking.rule.min_share:g} %"
                + "".join(f"; unphysical: {note}" for note in best.unphysical) + ")")
            found = (f"no missing effect found among {len(self.ranking.entries)} candidates{detail}. Validation "
                     f"mismatch {100 * base.nrmse_validation:.2f} %.")
        verdict = f"{found}{self._per_channel()}{self._equivalents()} Chebyshev residual on the final model: " \
                  f"{self.hybrids[-1].adequacy.message.rstrip('.')}."
        stopped = [ranking for ranking in self.ladder.rankings if ranking.fit_over_budget is not None]
        if stopped:
            verdict += (" Over budget, these rungs keep the parameters of the refit that found their effect (fitted to "
                        "a criterion step of 0.1, not to the last digits): " + "; ".join(
                            f"{r.baseline.name} (its fit stopped after {r.fit_over_budget:.1f} s)" for r in stopped)
                        + ". To fit them to the last digits, give those fits more time: --fit_budget "
                        f"(Ranker(fit_budget=), default {RUNG_FIT_BUDGET:g} times the refit).")
        undecided = [(ranking.baseline.name, e) for ranking in self.ladder.rankings for e in ranking.undecided]
        if undecided:
            verdict += (" Undecided (their refits stopped over budget): "
                        + "; ".join(f"{e.effect} on {name} ({e.undecided:.1f} s)" for name, e in undecided)
                        + ". To decide them, give the refits more time: --refit_budget (Ranker(refit_budget=), default "
                        f"{REFIT_BUDGET:g} times the rung's fit) or --budget (budget=, seconds for the whole diagnosis).")
        if self.discovery is not None and not self.discovery.searched:
            verdict += f" Discovery: {self.discovery.reason}."
        elif self.discovery is not None:
            judged = "recommended" if self.discovery.recommended else "not recommended"
            verdict += f" Discovered force: {self.discovery.text} ({judged}: {self.discovery.reason})."
        elif self.hybrids[-1].adequacy.inadequate:
            verdict += " To learn the form of what is missing, run the discovery (--discover, or discovery=Discoverer())."
        if self.probes is not None and self.probes.rows:
            verdict += " " + self.probes.describe()
        return verdict


    def _equivalents(self) -> str:
        """For each added effect that other candidates match (``Ranking.equivalent``): that the records cannot tell
        them apart on this physics, and what record would."""
        return "".join(
            f" {effect} and {', '.join(ranking.equivalent)} give the same output on this physics (their criteria "
            f"within {TIE:g}): these records cannot tell them apart, and the ladder names the first in the library's "
            f"order; a record of a signal between their places (the actuator's output, the quantity the sensor reads) "
            f"would." for effect, ranking in zip(self.ladder.added, self.ladder.rankings) if ranking.equivalent)

    def _per_channel(self) -> str:
        """With several output channels, each one's validation mismatch and where the missing effect shows most."""
        if len(self.channels) < 2:
            return ""
        most = self.shows_most
        where = (f"the missing effect shows most at output {most.name}" if self.ladder.added
                 else f"the physics fails most at output {most.name}")
        return (" Per output, validation mismatch: " + ", ".join(
            f"{c.name} {100 * c.physics:.2f} % -> {100 * c.final:.2f} %" if self.ladder.added
            else f"{c.name} {100 * c.physics:.2f} %" for c in self.channels) + f"; {where}.")


def _distinct(first: ModelScore, last: ModelScore) -> list[ModelScore]:
    return [first] if last is first else [first, last]


def _signals(records: list[Record]) -> tuple:
    """``(t, u, y)`` of the records: one batch, (time,), (records, time, ·), where they have one length; else one
    sequence each, ``(time_i,)``, ``(1, time_i, ·)``, which the residual's fit joins in time
    (:func:`~torchpaml.fit_chebyshev_hammerstein`)."""
    if len({len(r.t) for r in records}) == 1:
        return records[0].elapsed, torch.stack([r.u for r in records]), torch.stack([r.y for r in records])
    return [r.elapsed for r in records], [r.u[None] for r in records], [r.y[None] for r in records]


def _noise_like(record: Record, y_model: torch.Tensor) -> tuple[bool, float]:
    """Whether the training residual of every output channel is noise by effect size (its cross-correlation with the
    first input below :data:`NOISE_CORRELATION` at all but :data:`WHITE_SHARE` of the lags), and the largest share of
    a channel's residual that is linear in the input."""
    noise, linear_share = True, 0.0
    for c in range(record.y.shape[1]):
        whiteness = residual_analysis(record.u[:, 0], (record.y - y_model)[:, c])
        bound = max(whiteness.cross_correlation_bound, NOISE_CORRELATION)
        noise &= int((abs(whiteness.cross_correlation) > bound).sum()) <= WHITE_SHARE * len(whiteness.cross_lags)
        linear_share = max(linear_share, whiteness.linear_share)
    return noise, linear_share


def _residual_rms(records: list[Record], outputs: list[torch.Tensor]) -> tuple[float, ...]:
    """Each output channel's RMS of $y - \\hat y$ over ``records`` and the model's ``outputs`` on them."""
    if len(outputs) != len(records):
        return ()
    errors = torch.cat([r.y - y.reshape(r.y.shape) for r, y in zip(records, outputs)])
    return tuple(float(v) for v in errors.square().mean(0).sqrt())


def _uniform_step(record: Record) -> float | None:
    """The record's sampling interval where it is uniform, else ``None``."""
    try:
        return uniform_step(record.elapsed)
    except DataError:
        return None


def hybrid_residual(step: ModelScore, train: Record | Sequence[Record], alpha: float, deadline: float | None = None
                    ) -> tuple[ChebyshevHammerstein, torch.Tensor | list[torch.Tensor]]:
    """The Chebyshev-Hammerstein residual of the paper fitted on the training residual $y - \\hat y$ of ``step``'s
    fitted model (each record from its initial state), as :func:`diagnose` fits it on its first and last rung, and
    the model's training output $\\hat y$: (records, time, n_y) where the records have one length, else one
    (1, time_i, n_y) per record. ``alpha``: the residual's domain, max $|u|$ it takes
    (:class:`~torchpaml.DomainError` beyond). The records share one sampling interval (the first record's sets the
    residual's band). ``deadline``: a ``time.perf_counter()`` time at which the pole search stops (the diagnosis'
    budget); it prints its progress."""
    train = as_records(train)
    t, u, y = _signals(train)
    residual = ChebyshevHammerstein.for_sampling(alpha, uniform_step(train[0].elapsed), inputs=train[0].u.shape[1],
                                                 outputs=train[0].y.shape[1])
    outputs = [simulate_record(step.model, r, x0, solver=step.solver)
               for r, x0 in zip(train, step.train_states, strict=True)]
    y_physics = torch.cat(outputs) if isinstance(y, torch.Tensor) else outputs
    target = y - y_physics if isinstance(y, torch.Tensor) else [a - b for a, b in zip(y, y_physics, strict=True)]
    budget = Budget(f"fitting the Chebyshev residual on {step.name}",
                    deadline=math.inf if deadline is None else deadline)
    fit_chebyshev_hammerstein(residual, t, u, target, rtol=DECISION_TOLERANCE, budget=budget)
    return residual, y_physics


def _hybrid(step: ModelScore, train: list[Record], validation: list[Record], alpha: float,
            deadline: float | None, floor: float, initial_state: InitialState) -> HybridScore:
    """Fit the Chebyshev residual on the training residual of ``step``'s model and score the hybrid on the validation
    samples the physics was scored on (:func:`~torchpaml._diagnostics.ranking.scoring.scored_mismatch`); ``floor``:
    the records' noise floor (:func:`~torchpaml._diagnostics.analysis.noise_floor.noise_floor`)."""
    t, u, y = _signals(train)
    residual, y_physics = hybrid_residual(step, train, alpha, deadline)
    with torch.no_grad():
        hybrid_train = mismatch(joined_in_time(y), joined_in_time(y_physics) + per_record(residual, t, u))
        outputs = [y_model + residual(record.elapsed, record.u[None])[0]  # each record's filter from rest
                   for record, y_model in zip(validation, step.validation_outputs, strict=True)]
        hybrid_validation = scored_mismatch(validation, outputs, initial_state)
    noise, linear_share = _noise_like(train[0], joined_in_time(y_physics)[0, :len(train[0].t)])
    adequacy = assess_adequacy(step.nrmse_train, hybrid_train, step.nrmse_validation, hybrid_validation,
                               residual_white=noise, linear_share=linear_share,
                               noise_floor=floor)
    return HybridScore(step.name, step.nrmse_train, hybrid_train, step.nrmse_validation, hybrid_validation, adequacy,
                       residual)


#: The keywords :func:`diagnose` took before its stages were objects, and the stage each now belongs to.
LEGACY_RANKER = ("rule", "shortlist", "probe", "max_nfev", "refit_budget")


def diagnose(
    physics: AbstractPhysics,
    candidates: Sequence[AbstractEffect],
    train: Record | Sequence[Record],
    validation: Record | Sequence[Record],
    *,
    ranker: Ranker | None = None,
    initial_state: str | InitialState = Rest(),
    start_states: Sequence[torch.Tensor] | None = None,
    discovery: Discoverer | None = None,
    prober: Prober | None = Prober(),
    alpha: float | None = None,
    budget: float | None = DEFAULT_BUDGET,
    **legacy,
) -> Diagnosis:
    """Run the whole diagnosis (module docstring).

    Args:
        physics: the physics to diagnose (not modified); its learnable parameters are fitted.
        candidates: effects at zero strength.
        train: the training records.
        validation: the validation records.
        ranker: how each rung's candidates are ranked (:class:`~torchpaml.Ranker`; default ``Ranker()``).
        initial_state: where the records' simulations start: ``Rest()`` (or ``"rest"``) or ``Estimate()``
            (``"estimate"``; :mod:`~torchpaml._fit.initial_state`).
        start_states: with ``Estimate()``, the first fit's starting guesses of the training records' initial states.
        discovery: also discover a force outside the library (module docstring, step 4) with these settings
            (:class:`~torchpaml.Discoverer`; ``Discoverer(library=TermLibrary(terms=["x**2*sign(v)"]))`` adds the
            user's own terms); default ``None``: no discovery.
        prober: probe where the last rung's mismatch points (module docstring, step 5) with these settings
            (:class:`~torchpaml.Prober`); ``None``: no probes.
        alpha: Chebyshev domain of the residual; default 1.05 max |u| over all records.
        budget: seconds for the whole diagnosis, counted from the call (default
            :data:`~torchpaml._budget.DEFAULT_BUDGET`, 600 s; ``None``: no limit), printed in its first progress
            line: a refit still running then stops, and those not started are not run, each reported undecided
            (``EffectEvidence.undecided``, ``Discovery.undecided``, named in the verdict); a rung's fit keeps its
            refit's parameters (``Ranking.fit_over_budget``); the residual's pole search keeps its poles. Within it,
            each refit has its own limit (``Ranker.refit_budget``, :mod:`torchpaml._budget`).
        legacy: the keywords of the earlier signature, still taken with a ``DeprecationWarning``: ``discover`` and
            ``terms`` (now ``discovery=Discoverer(...)``), and ``rule``, ``shortlist``, ``probe``, ``max_nfev`` and
            ``refit_budget`` (now ``ranker=Ranker(...)``).
    """
    ranker, discovery = _stages(ranker, discovery, legacy)
    check_budget(budget)
    deadline = None if budget is None else time.perf_counter() + budget
    train, validation, initial_state = as_records(train), as_records(validation), as_initial_state(initial_state)
    _check_records(physics, candidates, train, validation, discovery, initial_state)
    log.info("diagnosing %s on %d training and %d validation record(s), %d samples; budget: %s (budget=, --budget)",
             physics.display_name, len(train), len(validation), sum(len(r.t) for r in train + validation),
             "none" if budget is None else f"{budget:.0f} s for the whole diagnosis")
    workers = min(2, torch.get_num_threads())  # the residual fits' threads: one where torch has one (a fleet's worker)
    with one_thread():  # one arithmetic path: every reduction of the diagnosis on one thread
        ladder = model_ladder(physics, candidates, train, validation, ranker=ranker, initial_state=initial_state,
                              start_states=start_states, deadline=deadline)
        base = ladder.steps[0]
        channels = channel_scores(base, ladder.final, validation)
        alpha = alpha or 1.05 * max(float(r.u.abs().max()) for r in train + validation)
        floor = noise_floor(train + validation, validation)  # one reading for both rungs
        log.info("fitting the Chebyshev residual on top")
        with ThreadPoolExecutor(workers) as pool:
            hybrids = list(pool.map(lambda step: _hybrid(step, train, validation, alpha, deadline, floor,
                                                         ladder.rankings[0].initial_state),
                                    _distinct(base, ladder.final)))
        complete = hybrids[-1].adequacy.complete
        probes = None if prober is None else prober.probe(ladder.rankings[-1], train, validation, ranker=ranker,
                                                          deadline=deadline, discovering=discovery is not None,
                                                          complete=complete, first=base, start=physics)
        found = None if discovery is None else _discovered(discovery, ladder, train, validation, deadline, complete)
        if probes is not None and found is not None:
            probes = probes.with_discovery(found)
        first = channels[0]
        return Diagnosis(ladder, first.residuals, first.by_input, first.by_output, hybrids, validation, found, channels,
                         probes)


def _discovered(discovery: Discoverer, ladder: Ladder, train: list[Record], validation: list[Record],
                deadline: float | None, complete: bool) -> Discovery:
    """Discovery on the ladder's last rung, then against the effects the ladder added (module docstring, step 5)."""
    if deadline is not None:
        log.info("discovery: %.0f s of the diagnosis' budget left", max(0.0, deadline - time.perf_counter()))
    found = discovery.discover(ladder.rankings[-1], train, validation, deadline, complete=complete)
    if ladder.added and found.recommended and found.discovered is not None:
        return _form_without_stand_ins(discovery, ladder, found, train, validation, deadline)
    if ladder.added:
        return _against_stand_ins(discovery, ladder, found, train, validation, deadline)
    return found


def _against_stand_ins(discovery: Discoverer, ladder: Ladder, found: Discovery, train: list[Record],
                       validation: list[Record], deadline: float | None) -> Discovery:
    """Discovery on the physics alone, competing with the effects the ladder added (module docstring, step 5): its
    form replaces them where the rule recommends it on the physics, the ladder's last rung does not beat it by the
    rule, and it has fewer fitted parameters (the simpler model); else ``found``, its reason saying what the form
    on the physics alone was and why it was not kept."""
    base = ladder.steps[0]
    log.info("discovery on %s alone, against the ladder's %s", base.name, ", ".join(ladder.found))
    alone = discovery.discover(ladder.rankings[0], train, validation, deadline)
    form, final, rule = alone.discovered, ladder.final, ladder.rankings[-1].rule
    if not alone.recommended or form is None:
        note = f"on {base.name} alone, discovery found no form to replace the ladder's effects ({alone.reason})"
        return replace(found, reason=f"{found.reason}; {note}")
    kept = _simpler_kept(form, final, ladder, rule)
    if kept is not None:
        return replace(alone, reason=f"on {base.name} alone: {alone.reason}; {kept}", replaces=list(ladder.found))
    sizes = len(form.estimate.parameters), len(final.estimate.parameters)
    why = f"it has {sizes[0]} fitted parameters against {sizes[1]}" if sizes[0] >= sizes[1] else \
        "the ladder's last rung beats it by the rule"
    note = (f"on {base.name} alone, discovery found {alone.text} (validation {100 * form.nrmse_validation:.2f} %), "
            f"not kept over the ladder's effects: {why}")
    return replace(found, reason=f"{found.reason}; {note}")


def _form_without_stand_ins(discovery: Discoverer, ladder: Ladder, found: Discovery, train: list[Record],
                            validation: list[Record], deadline: float | None) -> Discovery:
    """The form discovered on the ladder's last rung, refitted on the physics alone (module docstring, step 5): it
    replaces the ladder's effects where the last rung with the form does not beat it by the rule and it has fewer
    fitted parameters; else ``found``. A form with a width (a smoothed sign) keeps its rung: its width's range is
    the search's."""
    effect, base, rule = found.effect, ladder.steps[0], ladder.rankings[-1].rule
    if effect.width_names:
        return found
    terms = effect.terms_and_coefficients()
    pairs, coefficients = [(equation, term) for term, _, equation in terms], [c for _, c, _ in terms]
    budget = Budget(f"discovery: {found.text} on {base.name} alone", evaluations=REFIT_BUDGET * discovery.max_nfev,
                    deadline=math.inf if deadline is None else deadline)
    log.info("discovery: refitting %s on %s alone, without the ladder's %s", found.text, base.name,
             ", ".join(ladder.found))
    try:
        fitted = fit_closed_form(base.model, pairs, coefficients, {}, train, discovery.max_nfev,
                                 ladder.rankings[0].initial_state, budget, base.solver)
        alone = None if fitted is None else score_model(*fitted, validation, rule, ladder.rankings[0].initial_state)
    except (OverBudget, SimulationError):
        alone = None
    kept = None if alone is None else _simpler_kept(alone, found.discovered, ladder, rule)
    if kept is None:
        return found
    reason = f"{found.reason}; refitted on {base.name} alone, {kept}"
    return replace(found, physics=base, discovered=alone, effect=alone.model.effects["discovered"], reason=reason,
                   replaces=list(ladder.found))


def _simpler_kept(simple: ModelScore, rich: ModelScore, ladder: Ladder, rule: SelectionRule) -> str | None:
    """Why ``simple`` (the physics with a discovered form) is kept over ``rich`` (the ladder's effects, with or
    without the form): it has fewer fitted parameters and ``rich`` does not beat it by ``rule``; ``None`` where it
    is not kept."""
    sizes = len(simple.estimate.parameters), len(rich.estimate.parameters)
    if sizes[0] >= sizes[1] or rule.accepts(simple, rich):
        return None
    gain, share = simple.criterion - rich.criterion, 1 - rich.nrmse_validation / simple.nrmse_validation
    return (f"it reaches {100 * simple.nrmse_validation:.2f} % on validation; the ladder's {', '.join(ladder.found)} "
            f"({sizes[1]} fitted parameters, validation {100 * rich.nrmse_validation:.2f} %) do not beat it by the "
            f"rule (they change the criterion by {gain:+.1f} and the validation mismatch by {100 * share:.1f} %; "
            f"needed more than {rule.threshold:g} and {100 * rule.min_share:g} %), and it has {sizes[0]}: the "
            f"simpler model is kept, and the ladder's effects stood in for it")


def _stages(ranker: Ranker | None, discovery: Discoverer | None, legacy: dict) -> tuple[Ranker, Discoverer | None]:
    """The ranker and the discoverer, from the earlier signature's keywords where those are given (with a
    ``DeprecationWarning`` naming the replacement)."""
    unknown = sorted(set(legacy) - {"discover", "terms", *LEGACY_RANKER})
    if unknown:
        raise ConfigurationError(f"diagnose() got unexpected keyword(s) {unknown}; the ranking's settings go in "
                                 "ranker=Ranker(...), the discovery's in discovery=Discoverer(...)")
    if not legacy:
        return ranker or Ranker(), discovery
    warnings.warn(f"diagnose({', '.join(f'{k}=' for k in legacy)}) is deprecated: pass ranker=Ranker(...) and "
                  "discovery=Discoverer(library=TermLibrary(terms=...))", DeprecationWarning, stacklevel=3)
    options = {k: legacy[k] for k in LEGACY_RANKER if k in legacy}
    if options:
        if ranker is not None:
            raise ConfigurationError(f"give the ranking's settings once: ranker=Ranker(...) or {sorted(options)}")
        ranker = Ranker(**options)
    if legacy.get("discover"):
        if discovery is not None:
            raise ConfigurationError("give the discovery once: discovery=Discoverer(...) or discover=True")
        discovery = Discoverer(library=TermLibrary(terms=tuple(legacy.get("terms") or ())))
    return ranker or Ranker(), discovery


def _check_records(physics: AbstractPhysics, candidates: Sequence[AbstractEffect], train: list[Record],
                   validation: list[Record], discovery: Discoverer | None, initial_state: InitialState) -> None:
    """Before any fit: the records' channels are the physics', each output varies and keeps one unit across records
    (:mod:`~torchpaml._data.checks`), the physics runs on the first record, each record's time step can be in
    seconds for it, the discovery's terms parse, every record has more samples than twice the most parameters a
    fit takes and a uniform grid (the residual's exact filter), and each validation record is long enough to be scored
    after its start (:meth:`~torchpaml.InitialState.scored_from`)."""
    most = len(physics.learnable_names()) + max((sum(r["learnable"] for r in describe_parameters(c)) + len(c.shape)
                                                 for c in candidates), default=0)
    for record in train + validation:
        check_channels(physics, record)
        if len(record.t) <= 2 * most:
            raise DataError(f"record {record.name!r} has {len(record.t)} samples, too few to fit up to {most} "
                            f"parameters (the physics' and a candidate's) and judge the fit; give records of more "
                            f"than {2 * most} samples, or fix parameters")
        record.require_uniform("diagnose (its Chebyshev-Hammerstein residual, an exactly discretised filter)")
    for record in validation:
        initial_state.scored_from(record)
    check_outputs_vary(train + validation)
    check_scales_agree(train + validation)
    check_physics(physics, train[0].t, train[0].u)
    for record in train + validation:
        check_time_scale(physics, record)
    if discovery is not None:
        discovery.library.build(physics)  # a user term that does not parse is named before any fit
