"""The shortlist's refits (the ranking's step 3, :mod:`~torchpaml._diagnostics.ranking.steps`): which candidates are
refitted (:func:`cannot_pass`), each from its first-order start (:func:`refit_effect`) within its budget
(:class:`Refits`), and the best one's shape freed (:func:`free_shape`)."""

from __future__ import annotations

import copy
import functools
import logging
import math

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._budget import Budget, OverBudget
from torchpaml._data import Record
from torchpaml._data.simulation import simulate_record
from torchpaml._diagnostics.ranking.probes import assigned
from torchpaml._diagnostics.results import EffectEvidence, ModelScore
from torchpaml._diagnostics.ranking.scoring import score_model
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._errors import ConfigurationError, ResolutionError, SimulationError
from torchpaml._fit.initial_state import InitialState, as_initial_state
from torchpaml._fit.physics_fit import PhysicsEstimate, fit_physics
from torchpaml._metrics import mismatch
from torchpaml._parameters import unphysical_values
from torchpaml._simulate.sensitivity import raw_parameters
from torchpaml._simulate.solvers import Auto, Solver
from torchpaml._simulate.warm import WarmStart

__all__ = ["GATE_MARGIN", "REFIT_CRITERION_STEP", "RESCUE_FRACTIONS", "Refits", "SHAPE_FTOL", "cannot_pass",
           "effect_bounds", "free_shape", "refit_effect"]

log = logging.getLogger(__name__)

#: A refit stops when a step changes the training criterion $n\ln(\mathrm{SSE}/n)$ by less than this (its ``ftol``
#: is this over n): a hundredth of the threshold that decides. The effect that the ladder adds is fitted to the
#: last digits as the next rung's baseline.
REFIT_CRITERION_STEP = 0.1


#: A candidate is refitted only if its first-order score, multiplied by this margin, could pass the rule
#: (:func:`cannot_pass`): a refit may explain more than the first-order step, by this factor at most.
GATE_MARGIN = 4.0


#: Shares of the first-order move tried as a refit's start where the fit from the unmoved unknowns ends worse than the
#: baseline on the training records (:func:`refit_effect`).
RESCUE_FRACTIONS = (0.5, 0.25)


def refit_effect(extended: AbstractPhysics, name: str, start: float, train: list[Record], max_nfev: int,
                 initial_state: str | InitialState,
                 baseline: PhysicsEstimate | None = None, move: torch.Tensor | None = None, ftol: float = 1e-10,
                 budget: Budget | None = None, bounds: dict[str, tuple[float, float]] | None = None,
                 solver: Solver | None = None) -> PhysicsEstimate:
    """Fit ``extended`` from the first-order start (:func:`first_order`): the strength ``name`` at ``start`` and,
    given the ``baseline`` fit, its unknowns (raw parameters, then estimated initial states) moved by ``move``.

    The move is taken only where the simulation at it fits the training records better than the
    baseline (far from linear, as with an outflow that becomes a square root, the step can overshoot
    or blow up). Otherwise the unknowns stay, and the strength is halved while it breaks its constraint
    or blows up the simulation, down to 0. Where that fit ends worse than the baseline on the training
    records (a poor local optimum: the baseline, the effect at 0, fits better), half the move, then a
    quarter (:data:`RESCUE_FRACTIONS`), is tried as the start in the same way, and the better fit is kept.
    ``ftol``, ``budget`` (shared by every fit tried here; :class:`~torchpaml.OverBudget` ends the
    refit) and ``bounds`` (the effect's, :meth:`~torchpaml.AbstractEffect.bounds`) go to
    :func:`~torchpaml.fit_physics`, with ``Auto(start=solver)``: the step check starts where the fit of the
    physics under the effect ended (``solver``, default ``baseline.solver``).
    """
    initial_state = as_initial_state(initial_state)
    warm = [WarmStart() for _ in train]  # the check's simulations start the fit's first Newton solves
    solver = Auto(start=solver if solver is not None or baseline is None else baseline.solver)
    fit = functools.partial(fit_physics, extended, train, max_nfev=max_nfev, initial_state=initial_state, ftol=ftol,
                            budget=budget, bounds=bounds, solver=solver)
    states = None if baseline is None else initial_state.carried(baseline.initial_states)
    if baseline is None or move is None:
        return _halving_strength(extended, name, start, fit, states)
    raw = list(raw_parameters(extended, list(baseline.parameters)).values())
    origin = [tensor.detach().clone() for tensor in raw]

    def moved_start(fraction: float) -> tuple[bool, list[torch.Tensor] | None]:
        """Whether ``fraction`` of the move fits the training records better than the baseline (the model left
        there), and the initial states it moves to."""
        shifted = None if states is None else [x + fraction * d for x, d in zip(states, move[len(origin):].split(
            [x.numel() for x in states]), strict=True)]
        with torch.no_grad():
            for tensor, value, delta in zip(raw, origin, move, strict=False):  # the move's tail: initial states'
                tensor.copy_(value + fraction * delta)
        better = (assigned(extended, name, fraction * start)
                  and _training_mismatch(extended, train, shifted, warm, solver) < baseline.mismatch)
        return better, shifted

    better, shifted = moved_start(1.0)
    if better:
        return fit(start_states=shifted, warm=warm)
    with torch.no_grad():
        for tensor, value in zip(raw, origin, strict=True):
            tensor.copy_(value)
    estimate = _halving_strength(extended, name, start, fit, states)
    if estimate.mismatch <= baseline.mismatch:
        return estimate
    fitted_state = copy.deepcopy(extended.state_dict())
    for fraction in RESCUE_FRACTIONS:
        better, shifted = moved_start(fraction)
        if better:
            try:
                rescued = fit(start_states=shifted, warm=warm)
            except SimulationError:  # a ResolutionError too: the fit from the unmoved unknowns stands
                break
            if rescued.mismatch < estimate.mismatch:
                return rescued
            break
    extended.load_state_dict(fitted_state)
    return estimate


def _halving_strength(extended: AbstractPhysics, name: str, start: float, fit,
                      states: list[torch.Tensor] | None) -> PhysicsEstimate:
    """``fit`` from the strength ``start``, halved while it breaks its constraint or blows up the simulation, down
    to 0 (:func:`refit_effect`)."""
    for strength in [start * 0.5**i for i in range(20)] + [0.0]:
        if not assigned(extended, name, strength):  # beyond the parameter's constraint
            continue
        try:
            return fit(start_states=states)
        except ResolutionError:
            raise  # the fit's optimum, not its start, is unresolved
        except SimulationError:
            if strength == 0.0:
                raise
    raise ConfigurationError(f"{name!r} cannot be 0, but an effect's strength parameter must switch it off at 0")


def _training_mismatch(physics: AbstractPhysics, train: list[Record], states: list[torch.Tensor] | None,
                       warm: list[WarmStart],
                       solver: Solver) -> float:
    r"""The :func:`~torchpaml.mismatch` over the training records from ``states`` (or rest), simulated by the
    solver that a fit with ``solver`` starts from (:meth:`~torchpaml.Solver.stepping` of ``Auto(start=solver)``; the fit then
    checks its own step); inf if the simulation blows up. Each record's solution is left in its
    :class:`~torchpaml.WarmStart` of ``warm``."""
    solver = Auto(start=solver).stepping()
    try:
        outputs = [simulate_record(physics, r, x0, solver=solver, warm=w)[0]
                   for r, x0, w in zip(train, states or [None] * len(train), warm, strict=True)]
    except SimulationError:
        return math.inf
    return mismatch(torch.cat([r.y for r in train]), torch.cat(outputs))


#: The shape-freed refit's ``ftol``: to the last digits (:func:`~torchpaml.fit_physics`' default), not a refit's
#: early stop. Its end decides whether the shape is freed, and stopped early it depends on the path: on the cascaded
#: tanks' second rung (``upper_overflow``, its rim ``h`` freed) it ended at 6.70 % on training in one run and at
#: 4.63 % on one thread and on records perturbed by 1e-12, and the ladders went on to different effects; run to the
#: last digits, the three agree.
SHAPE_FTOL = 1e-10


def effect_bounds(model: AbstractPhysics, records: list[Record]) -> dict[str, tuple[float, float]]:
    """The bounds of every effect of ``model`` on ``records`` (:meth:`~torchpaml.AbstractEffect.bounds`)
    on those of its parameters that are learnable, each widened to take the parameter's current value (a start
    beyond a bound, a user's, is kept as it is): an effect's bounds hold in every refit where its parameters move,
    the rungs after it was added included (a Coulomb friction's width freed on one rung runs away on the next
    without its bound)."""
    learnable, values = set(model.learnable_names()), model.physical_parameters()
    bounds = {}
    for name in model.effect_names():
        for parameter, (lower, upper) in model.effects[name].bounds(records).items():
            key = f"{name}.{parameter}"
            if key in learnable:
                bounds[key] = (min(lower, values[key]), max(upper, values[key]))
    return bounds


def free_shape(entry: EffectEvidence, train: list[Record], validation: list[Record], rule: SelectionRule,
               max_nfev: int, initial_state: InitialState, budget: Budget) -> None:
    """``entry``'s refit replaced by its model refitted with the effect's shape parameters freed (to
    :data:`SHAPE_FTOL`, within every effect's bounds, :func:`effect_bounds`), if that beats it by the rule's
    threshold; a shape refit over ``budget`` leaves the refit and says so in ``entry.refit_reason``."""
    score = entry.refit
    shape = score.model.effects[entry.effect].shape
    if not shape:
        return
    freed = copy.deepcopy(score.model).set_learnable(*(f"{entry.effect}.{name}" for name in shape))
    bounds = effect_bounds(freed, train)
    states = initial_state.carried(score.train_states)
    try:
        estimate = fit_physics(freed, train, max_nfev=max_nfev, initial_state=initial_state, start_states=states,
                               ftol=SHAPE_FTOL, budget=budget, bounds=bounds, solver=Auto(start=score.solver))
    except OverBudget as over:
        entry.refit_reason += f"; its shape ({', '.join(shape)}) not freed: over budget ({over.seconds:.1f} s)"
        return
    except SimulationError:
        return
    candidate = score_model(freed, estimate, validation, rule, initial_state)
    if score.criterion - candidate.criterion > rule.threshold:
        entry.refit, entry.seconds = candidate, (entry.seconds or 0.0) + budget.elapsed  # the rung's fit made it too


def cannot_pass(score: float, rule: SelectionRule, validation: list[Record], extended: AbstractPhysics,
                base) -> str | None:
    r"""Why a candidate whose first-order score is ``score`` cannot pass ``rule``, even if its refit explained
    :data:`GATE_MARGIN` times that share $s$ of the residual's energy; ``None`` where it could.

    At the share $s' = \min(1, M s)$ the mismatch falls by $1 - \sqrt{1 - s'}$ and the criterion on the $n$ validation
    samples by $-n\ln(1 - s')$ less the penalty of the candidate's parameters: the rule needs ``min_share`` and more
    than ``threshold``. The score is measured on the training records, the rule on validation: the margin covers
    both that and what a refit finds beyond the first-order step.
    """
    reachable = min(1.0 - 1e-12, GATE_MARGIN * score)
    share = 1.0 - math.sqrt(1.0 - reachable)
    samples = sum(r.y.numel() for r in validation)
    added = len(extended.learnable_names()) - len(base.learnable_names())
    gain = rule.value(1.0, samples, 0) - rule.value(1.0 - reachable, samples, added)
    at = f"its first-order score {score:.3g} predicts at most"
    if share < rule.min_share:
        return (f"{at} a {100 * share:.2g} % fall of the validation mismatch, even at {GATE_MARGIN:g}x the score "
                f"(the rule needs {100 * rule.min_share:g} %)")
    if gain <= rule.threshold:
        return f"{at} a criterion gain of {gain:.1f}, even at {GATE_MARGIN:g}x the score (the rule needs {rule.threshold:g})"
    return None


class Refits:
    """The shortlist's refits on one rung: each from its first-order start (:func:`refit_effect`), within its budget
    (``template``'s limits, counted from the refit's own start), scored on validation."""

    def __init__(self, name: str, train: list[Record], validation: list[Record], fit: PhysicsEstimate,
                 baseline: ModelScore, rule: SelectionRule, initial_state: InitialState, max_nfev: int,
                 template: Budget):
        self.name, self.train, self.validation, self.fit, self.baseline = name, train, validation, fit, baseline
        self.rule, self.initial_state, self.max_nfev, self.template = rule, initial_state, max_nfev, template
        self.ftol = REFIT_CRITERION_STEP / sum(r.y.numel() for r in train)

    def budget(self, effect: str) -> Budget:
        """A fresh budget for the refit of ``effect``, with the rung's limits."""
        return self.template.restarted(f"refitting {self.name} + {effect}")

    def run(self, entry: EffectEvidence, extended: AbstractPhysics, strength: str, move: torch.Tensor,
            bounds: dict[str, tuple[float, float]]) -> None:
        """Refit ``entry``'s model and record in ``entry`` the result, the failure, or that it is undecided."""
        budget = self.budget(entry.effect)
        if budget.expired:
            entry.undecided, entry.refit_reason = 0.0, "undecided: the diagnosis' budget was spent before its refit"
            return
        log.info("refitting %s + %s (at most %s)", self.name, entry.effect, budget.describe())
        try:
            refit = refit_effect(extended, strength, entry.first_order_strength, self.train, self.max_nfev,
                                 self.initial_state, self.fit, move, self.ftol, budget, bounds)
            entry.seconds = budget.elapsed
        except OverBudget as over:
            entry.undecided, entry.refit_reason = over.seconds, f"undecided: over budget ({over.seconds:.1f} s)"
            log.info("%s + %s undecided: over budget (%.1f s)", self.name, entry.effect, over.seconds)
            return
        except ResolutionError as error:
            entry.failure = f"refit unresolved: {error}"
            return
        except SimulationError as error:  # the refit drove a rate of the effect beyond what RK4 integrates
            entry.failure = f"refit blew up: {error}; parameters {extended.physical_parameters()}"
            return
        try:
            entry.refit = score_model(extended, refit, self.validation, self.rule, self.initial_state)
        except SimulationError as error:  # stable on the training records, unstable on a validation record
            entry.failure = (f"the refitted model blows up on validation: {error}; parameters "
                             f"{extended.physical_parameters()}")
            return
        entry.improvement = self.baseline.criterion - entry.refit.criterion
        entry.unphysical = unphysical_values(entry.refit.rows())
