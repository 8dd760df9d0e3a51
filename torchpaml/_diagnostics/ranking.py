r"""Which effect is missing: rank candidate effects by a first-order score, then by refitted validation error.

1. **Baseline.** The physics' learnable parameters are fitted to the training records
   (:func:`~torchpaml._fit.fit_physics`), leaving the residual
   $r = (y - \hat y)/\|y\|$ and the sensitivities $J = \partial r/\partial\rho$ of the physics' own
   parameters.
2. **First-order score** (the tangent-space idea of Kuang & Lin). Each candidate $c$ is added at
   strength $k$; at $k = 0$ the model is unchanged. Its output direction is the secant
   $d_c = [\hat y(\delta) - \hat y(0)]/\|y\|$ for a small probe strength $\delta$. What the physics'
   own parameters already explain is removed, $\tilde d_c = (I - J J^+)\, d_c$ (the numerically null directions of
   $J$ left out, so that rounding does not decide: :func:`_determined`), and the score is the
   share of the residual's energy that a step along $\tilde d_c$ removes:

   $$ s_c = \frac{(\tilde d_c^\top r)^2}{\|\tilde d_c\|^2\,\|r\|^2} \in [0, 1]. $$

   Some effects enter at second order: $\tanh(s u)/s = u - s^2u^3/3 + \dots$ is even in $s$.
   The order $q$ is read off $\|\hat y(2\delta) - \hat y(0)\| / \|\hat y(\delta) - \hat y(0)\| \approx 2^q$;
   for $q = 2$ only a positive coefficient $\beta = \tilde d_c^\top r / \|\tilde d_c\|^2$ is reachable
   ($\beta = (k/\delta)^2$), so $s_c = 0$ when $\beta \le 0$. The first-order strength
   $k_1 = \delta\,\beta^{1/q}$ starts the refit. The probes' outputs come from the tangent-linear
   model when the base is linear (:class:`TangentLinear`, no nonlinear simulation), else from RK4
   simulations warm-started from the base's trajectory (:class:`Secant`).
3. **Refit.** The ``shortlist`` best-scored candidates are refitted with the physics
   (all parameters learnable as in the physics, plus the effect's) on the training records. Each
   refit starts from the first-order Gauss-Newton step: the strength $k_1$, and the physics' own
   unknowns moved by $-J^+(r - \beta d_c)$. It stops when a step changes the training criterion by
   less than :data:`REFIT_CRITERION_STEP` (0.1, a hundredth of the threshold). When
   the best of them has shape parameters (:attr:`~torchpaml._physics.AbstractEffect.shape`: the
   width of Coulomb friction's smoothed sign), it is refitted once more with them freed, and that
   refit is kept when it lowers the criterion by more than ``threshold``: the data asks for another shape.
   A refit whose optimum fails the step check (:mod:`torchpaml._fit.resolution`: its output depends on
   the RK4 step beyond what substeps resolve) has no result; its evidence says why (``failure``).
4. **Rank** by the information criterion on the validation records (:class:`~torchpaml._diagnostics.SelectionRule`:
   BIC or AIC). The best candidate is *recommended* when the rule accepts it over the baseline
   (criterion lower by more than ``threshold``, validation mismatch lower by ``min_share``, training
   mismatch not higher) and
   - its refitted parameters lie in their declared physical ranges (``physical`` of
     :class:`~torchpaml._parameters.PhysicalParameter`: a Coulomb level or a drag coefficient >= 0, a
     share of sin x in [0, 1]). An unphysical refit is flagged in its evidence and passed over.
   Candidates outside the shortlist follow, by score, without a refit.
"""

from __future__ import annotations

import copy
import functools
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import torch
from torch import nn

from torchpaml._data import Experiment
from torchpaml._diagnostics.selection import SelectionRule
from torchpaml._errors import ConfigurationError, ResolutionError, SimulationError
from torchpaml._budget import REFIT_BUDGET, Budget, OverBudget
from torchpaml._fit.physics_fit import PhysicsEstimate, estimate_initial_state, fit_physics
from torchpaml._metrics import mismatch
from torchpaml._parameters import unphysical_values, with_uncertainty
from torchpaml._data.simulation import simulate_record
from torchpaml._simulate.sensitivity import raw_parameters
from torchpaml._simulate.solvers import Auto, Solver, continued, engine_solver
from torchpaml._diagnostics.probes import Secant, TangentLinear, assigned
from torchpaml._simulate.warm import WarmStart
from torchpaml._physics.effects import AbstractEffect

__all__ = ["EffectEvidence", "GATE_MARGIN", "ModelScore", "REFIT_CRITERION_STEP", "Ranking", "rank_missing_effects",
           "refit_effect", "score_model"]

log = logging.getLogger(__name__)

#: A refit stops when a step changes the training criterion $n\ln(\mathrm{SSE}/n)$ by less than this (its ``ftol``
#: is this over n): a hundredth of the threshold that decides. The effect that the ladder adds is fitted to the
#: last digits as the next rung's baseline.
REFIT_CRITERION_STEP = 0.1
#: A candidate is refitted only if its first-order score, multiplied by this margin, could pass the rule
#: (:func:`_cannot_pass`): a refit may explain more than the first-order step, by this factor at most.
GATE_MARGIN = 4.0
#: A direction of the physics' unit-scaled Jacobian whose singular value is below this share of the largest is
#: numerically null (:func:`_determined`).
NULL_DIRECTION = 1e-10


@dataclass
class ModelScore:
    """A fitted model's errors: mismatch (fraction) on training and validation, and the criterion on validation.

    It carries what scoring computed: the initial states of the training and validation records, each
    (n_state,), and the model's output on each validation record, (time, n_y), so that what is drawn or
    analysed later is the output that was scored; the solver the fit resolved (``PhysicsEstimate.solver``: pass
    it to simulate ``model`` as it was scored); and the 95 % ``interval`` of each fitted parameter.
    """

    name: str
    equation: str
    parameters: dict[str, float]
    nrmse_train: float
    nrmse_validation: float
    criterion: float
    model: torch.nn.Module = field(repr=False)
    uncertainty: dict[str, float] = field(default_factory=dict)
    warning: str | None = None
    train_states: list[torch.Tensor] = field(default_factory=list, repr=False)
    validation_states: list[torch.Tensor] = field(default_factory=list, repr=False)
    validation_outputs: list[torch.Tensor] = field(default_factory=list, repr=False)
    solver: Solver = field(default_factory=Auto, repr=False)
    interval: dict[str, tuple[float, float]] = field(default_factory=dict, repr=False)

    def rows(self) -> list[dict]:
        """The model's parameter rows (:func:`~torchpaml._parameters.describe_parameters`) with the fit's standard
        errors and 95 % intervals."""
        return with_uncertainty(self.model._rows(), self.uncertainty, self.interval)

    def describe(self) -> str:
        """The model's parameter table with the fit's standard errors and 95 % intervals
        (:meth:`~torchpaml.AbstractPhysics.describe`)."""
        return self.model.describe(_Spread(self.uncertainty, self.interval))


@dataclass(frozen=True)
class _Spread:
    """A fit's standard errors and intervals, as :meth:`~torchpaml.AbstractPhysics.describe` reads them."""

    std: dict[str, float]
    interval: dict[str, tuple[float, float]]


@dataclass
class EffectEvidence:
    """One candidate's evidence: its first-order score and, if refitted, its refitted model's errors.

    ``improvement`` is the baseline's criterion minus the candidate's (positive: better). ``failure``: why a
    shortlisted refit has no result (its optimum fails the step check, :mod:`torchpaml._fit.resolution`, or its
    simulation blows up: a lag driven towards 0 is a rate beyond what RK4 integrates), or why
    the candidate was not scored (its own states blow up at zero strength). ``refit_reason`` says why the
    candidate was or was not refitted; ``undecided`` is the seconds its refit ran before it stopped over its budget
    (:mod:`torchpaml._budget`; 0 where the diagnosis' budget was spent before it started), else ``None``.
    """

    effect: str
    equation: str
    score: float
    order: int
    first_order_strength: float
    refit: ModelScore | None = None
    improvement: float | None = None
    unphysical: list[str] = field(default_factory=list)
    failure: str | None = None
    refit_reason: str = ""
    undecided: float | None = None


@dataclass
class Ranking:
    """The baseline and the candidates, best first (module docstring), and the rule and initial-state option they
    were ranked by (discovery on this ranking uses both)."""

    baseline: ModelScore
    entries: list[EffectEvidence]
    rule: SelectionRule = field(default_factory=SelectionRule)
    skipped: dict[str, str] = field(default_factory=dict)
    initial_state: Literal["rest", "estimate"] = "rest"

    @property
    def recommended(self) -> EffectEvidence | None:
        """The best physical refitted candidate if :attr:`rule` accepts it over the baseline, else ``None``."""
        best = next((e for e in self.entries if e.refit is not None and not e.unphysical), None)
        return best if best is not None and self.rule.accepts(self.baseline, best.refit) else None

    @property
    def undecided(self) -> list[EffectEvidence]:
        """The candidates whose refit stopped over its budget: the ranking cannot tell whether they would win."""
        return [e for e in self.entries if e.undecided is not None]


def as_records(experiments: Experiment | Sequence[Experiment]) -> list[Experiment]:
    return [experiments] if isinstance(experiments, Experiment) else list(experiments)


def score_model(
    physics,
    fit: PhysicsEstimate,
    validation: Sequence[Experiment],
    rule: SelectionRule | None = None,
    initial_state: Literal["rest", "estimate"] = "rest",
) -> ModelScore:
    """The fitted ``physics``' mismatch on training (from ``fit``) and validation, and ``rule``'s criterion on
    validation.

    With ``initial_state="estimate"`` each validation record starts from the state that best explains
    it (:func:`~torchpaml._fit.estimate_initial_state`, the parameters fixed), as MATLAB's ``compare`` does.
    """
    sse, n, norm = 0.0, 0, 0.0
    starts = [estimate_initial_state(physics, r, solver=continued(fit.solver)) if initial_state == "estimate" else None
              for r in validation]
    outputs = []
    for record, x0 in zip(validation, starts, strict=True):
        y_model = simulate_record(physics, record, x0, solver=fit.solver)[0]
        outputs.append(y_model)
        sse += float(torch.sum((record.y - y_model) ** 2))
        norm += float(torch.sum(record.y**2))
        n += record.y.numel()
    value = (rule or SelectionRule()).value(sse, n, len(fit.parameters))
    equation = physics.equation() if hasattr(physics, "equation") else physics.display_name
    return ModelScore(physics.display_name, equation, physics.physical_parameters(), fit.mismatch,
                      (sse / norm) ** 0.5, value, physics, dict(fit.uncertainty.std), fit.uncertainty.warning,
                      fit.initial_states, [physics.initial_state(1)[0] if x0 is None else x0 for x0 in starts],
                      outputs, fit.solver, dict(fit.uncertainty.interval))


class _Engines:
    """The probe engine for each candidate, each built once, with the base's own output it computes (the
    reference of the zero-strength check): the tangent-linear model around a linear base for an effect
    without states of its own, else secants by the fixed-step solver the base was fitted with."""

    def __init__(self, base, train: list[Experiment], fit: PhysicsEstimate, scale: float):
        self.base, self.train, self.initial_states, self.scale = base, train, fit.initial_states, scale
        self.solver = engine_solver(fit.solver)
        self.built: dict[str, tuple[TangentLinear | Secant, torch.Tensor] | None] = {}

    def of(self, effect: AbstractEffect) -> tuple[TangentLinear | Secant, torch.Tensor]:
        kind = "secant" if effect.own_states else "linear"
        if kind == "linear" and kind not in self.built:
            self.built[kind] = self._with_reference(TangentLinear.of(self.base, self.train, self.initial_states))
        if self.built.get(kind) is None:
            kind = "secant"
            if kind not in self.built:
                self.built[kind] = self._with_reference(Secant(self.base, self.train, self.initial_states,
                                                                              self.solver))
        return self.built[kind]

    def _with_reference(self, engine):
        return None if engine is None else (engine, engine.outputs(self.base) / self.scale)


@functools.lru_cache(maxsize=1)  # one rung's Jacobian, decomposed once for every candidate's probes (a tensor hashes by id)
def _determined(J: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""The directions of the physics' unit-scaled Jacobian that are not numerically null: $J D^{-1} = U S V^\top$
    ($D$ the columns' norms) truncated to the singular values of at least :data:`NULL_DIRECTION` times the largest.
    Returns $U_k$ (samples, k), $S_k$, $V_k^\top$ (k, unknowns) and $D$.

    A parameter that does not move the output (one at the limit of its constraint) or an exact degeneracy leaves a
    singular value at the rounding level (1e-18 on the cascaded tanks' third rung), and a least squares of the full
    $J$ keeps or drops that direction by its last digits, which move with the process's memory layout: there, runs
    with PYTHONHASHSEED 0 and 1 scored the same candidate 0.61 and 0.35 and climbed different ladders. Cut at
    1e-10, both score 0.73."""
    scale = J.norm(dim=0).clamp_min(1e-300)
    U, S, Vh = torch.linalg.svd(J / scale, full_matrices=False)
    keep = S >= NULL_DIRECTION * S[0] if len(S) else S > 0
    return U[:, keep], S[keep], Vh[keep], scale


def _physics_step(J: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    r"""$-J^+ v$ (unknowns,): the Gauss-Newton step of the physics' own unknowns that removes ``v`` (samples,), by the
    pseudo-inverse of :func:`_determined`'s directions (none along a numerically null one)."""
    U, S, Vh, scale = _determined(J)
    return -(Vh.T @ ((U.T @ v) / S)) / scale


def _beyond_physics(d: torch.Tensor, J: torch.Tensor) -> tuple[torch.Tensor, float]:
    r"""$\tilde d = (I - U_k U_k^\top) d$, the part of the output direction ``d`` (samples,) that the physics' own
    parameters (``J``'s columns, :func:`_determined`) cannot make, and its energy $\|\tilde d\|^2$."""
    Q = _determined(J)[0]
    projected = d - Q @ (Q.T @ d)
    return projected, float(projected @ projected)


def _share(projected: torch.Tensor, energy: float, r: torch.Tensor) -> float:
    r"""The share of the residual's energy that a step along ``projected`` removes,
    $(\tilde d^\top r)^2 / (\|\tilde d\|^2 \|r\|^2)$."""
    return float(projected @ r) ** 2 / (energy * float(r @ r))


def _first_order(extended, name: str, fit: PhysicsEstimate, scale: float, probe: float,
                 reference: torch.Tensor, engine: TangentLinear | Secant) -> tuple[float, int, float, torch.Tensor]:
    r"""(score, order q, first-order strength, move) of the effect whose strength parameter is ``name``
    (module docstring).

    The strength is probed at 0, δ, 2δ and -δ. An effect that moves the output the same way at ±δ
    (second order, or an absolute value such as the dead zone's |d|) can only add a positive multiple
    of its direction, so a negative coefficient scores 0.

    ``move`` (unknowns,) is the rest of the Gauss-Newton step from the baseline, for the physics' own
    unknowns (``fit.jacobian``'s columns): with the effect's output change $\beta d_c$ at the first-order
    strength, $\Delta\rho = -J^+(r - \beta d_c)$. The refit starts from both (:func:`refit_effect`).
    """
    outputs = [None if out is None else out / scale
               for out in engine.probes(extended, name, (0.0, probe, 2 * probe, -probe))]
    if outputs[0] is None:
        raise ConfigurationError(f"{name!r} cannot be 0, but an effect's strength parameter must switch it off at 0; "
                         "give it a constraint that allows 0 (e.g. Real())")
    extended.assign(**{name: 0.0})
    outputs = [out if out is not None else outputs[0] for out in outputs]
    off = float(torch.linalg.vector_norm(outputs[0] - reference) / torch.linalg.vector_norm(reference))
    if off > 1e-3:
        raise ConfigurationError(
            f"effect {name.partition('.')[0]!r} changes the model at zero strength (by {100 * off:.2g} % of the "
            f"output); its strength parameter {name!r} must switch the effect off at 0. Rewrite the effect so that "
            "its first declared parameter scales it"
        )
    d1, d2, d_minus = (outputs[i] - outputs[0] for i in (1, 2, 3))
    size = float(torch.linalg.vector_norm(d1))
    J, r = fit.jacobian, fit.residual
    still = torch.zeros(J.shape[1], dtype=J.dtype)
    if size == 0.0:
        return 0.0, 1, 0.0, still  # the effect does not act on this record
    order = 2 if float(torch.linalg.vector_norm(d2)) / size > 2**1.5 else 1
    one_sided = float(torch.linalg.vector_norm(d_minus - d1)) < 0.5 * size
    projected, energy = _beyond_physics(d1, J)
    if energy <= 1e-20 * size**2:
        return 0.0, order, 0.0, still  # the physics' own parameters already make this move
    beta = float(projected @ r) / energy
    if one_sided and beta <= 0:
        return 0.0, order, probe, still
    score = _share(projected, energy, r)
    move = _physics_step(J, r - beta * d1)
    return score, order, probe * (beta if order == 1 else beta ** (1 / order)), move


def _by_promise(base, candidate: AbstractEffect, train: list[Experiment], fit: PhysicsEstimate, delta: float,
                reference: torch.Tensor, engine: TangentLinear | Secant, scale: float) -> list[tuple[dict[str, float], nn.Module]]:
    r"""``(setting, base + candidate)`` for each of the candidate's starts (:meth:`~AbstractEffect.starts`), the most
    promising first: by the unsigned share of the residual that one probe at strength ``delta`` explains,
    $(\tilde d^\top r)^2 / (\|\tilde d\|^2 \|r\|^2)$ with $d$ taken against the base's output. One probe per start
    instead of :func:`_first_order`'s four; a start whose probe blows up comes last."""
    name = f"{candidate.name}.{candidate.strength}"
    models = []
    for setting in candidate.starts(train):
        models.append((setting, (copy.deepcopy(base) + copy.deepcopy(candidate)).assign(
            **{f"{candidate.name}.{key}": value for key, value in setting.items()})))
    if len(models) == 1:
        return models

    def promise(model) -> float:
        out = engine.probes(model, name, (delta,))[0]
        if out is None:
            return -1.0
        projected, energy = _beyond_physics(out / scale - reference, fit.jacobian)
        return 0.0 if energy == 0.0 else _share(projected, energy, fit.residual)

    return sorted(models, key=lambda pair: -promise(pair[1]))


#: Shares of the first-order move tried as a refit's start where the fit from the unmoved unknowns ends worse than the
#: baseline on the training records (:func:`refit_effect`).
RESCUE_FRACTIONS = (0.5, 0.25)


def refit_effect(extended, name: str, start: float, train: list[Experiment], max_nfev: int, initial_state: str,
                 baseline: PhysicsEstimate | None = None, move: torch.Tensor | None = None, ftol: float = 1e-10,
                 budget: Budget | None = None, bounds: dict[str, tuple[float, float]] | None = None,
                 solver: Solver | None = None) -> PhysicsEstimate:
    """Fit ``extended`` from the first-order start (:func:`_first_order`): the strength ``name`` at ``start`` and,
    given the ``baseline`` fit, its unknowns (raw parameters, then estimated initial states) moved by ``move``.

    The move is taken only where the simulation at it fits the training records better than the
    baseline (far from linear, as with an outflow that becomes a square root, the step can overshoot
    or blow up). Otherwise the unknowns stay, and the strength is halved while it breaks its constraint
    or blows up the simulation, down to 0. Where that fit ends worse than the baseline on the training
    records (a poor local optimum: the baseline, the effect at 0, fits better), half the move, then a
    quarter (:data:`RESCUE_FRACTIONS`), is tried as the start in the same way, and the better fit is kept.
    ``ftol``, ``budget`` (shared by every fit tried here; :class:`~torchpaml._budget.OverBudget` ends the
    refit) and ``bounds`` (the effect's, :meth:`~torchpaml._physics.AbstractEffect.bounds`) go to
    :func:`~torchpaml._fit.fit_physics`, with ``Auto(start=solver)``: the step check starts where the fit of the
    physics under the effect ended (``solver``, default ``baseline.solver``).
    """
    warm = [WarmStart() for _ in train]  # the check's simulations start the fit's first Newton solves
    solver = continued(solver if solver is not None or baseline is None else baseline.solver)
    fit = functools.partial(fit_physics, extended, train, max_nfev=max_nfev, initial_state=initial_state, ftol=ftol,
                            budget=budget, bounds=bounds, solver=solver)
    states = None if baseline is None or initial_state != "estimate" else baseline.initial_states
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


def _halving_strength(extended, name: str, start: float, fit, states: list[torch.Tensor] | None) -> PhysicsEstimate:
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


def _training_mismatch(physics, train: list[Experiment], states: list[torch.Tensor] | None, warm: list[WarmStart],
                       solver: Solver) -> float:
    r"""The :func:`~torchpaml._metrics.mismatch` over the training records from ``states`` (or rest), simulated by the
    solver that a fit with ``solver`` starts from (:func:`~torchpaml._simulate.solvers.engine_solver`; the fit then
    checks its own step); inf if the simulation blows up. Each record's solution is left in its
    :class:`~torchpaml.WarmStart` of ``warm``."""
    solver = engine_solver(solver)
    try:
        outputs = [simulate_record(physics, r, x0, solver=solver, warm=w).flatten()
                   for r, x0, w in zip(train, states or [None] * len(train), warm, strict=True)]
    except SimulationError:
        return math.inf
    return mismatch(torch.cat([r.y.flatten() for r in train]), torch.cat(outputs))


def _free_shape(entry: EffectEvidence, train: list[Experiment], validation: list[Experiment], rule: SelectionRule,
                max_nfev: int, initial_state: str, ftol: float, budget: Budget,
                bounds: dict[str, tuple[float, float]]) -> None:
    """``entry``'s refit replaced by its model refitted with the effect's shape parameters freed, if that beats it by
    the rule's threshold; a shape refit over ``budget`` leaves the refit and says so in ``entry.refit_reason``."""
    score = entry.refit
    shape = score.model.effects[entry.effect].shape
    if not shape:
        return
    freed = copy.deepcopy(score.model).set_learnable(*(f"{entry.effect}.{name}" for name in shape))
    states = score.train_states if initial_state == "estimate" else None
    try:
        estimate = fit_physics(freed, train, max_nfev=max_nfev, initial_state=initial_state, start_states=states,
                               ftol=ftol, budget=budget, bounds=bounds, solver=continued(score.solver))
    except OverBudget as over:
        entry.refit_reason += f"; its shape ({', '.join(shape)}) not freed: over budget ({over.seconds:.1f} s)"
        return
    except SimulationError:
        return
    candidate = score_model(freed, estimate, validation, rule, initial_state)
    if score.criterion - candidate.criterion > rule.threshold:
        entry.refit = candidate


def _cannot_pass(score: float, rule: SelectionRule, validation: list[Experiment], extended, base) -> str | None:
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


class _Refits:
    """The shortlist's refits on one rung: each from its first-order start (:func:`refit_effect`), within its budget
    (``template``'s limits, counted from the refit's own start), scored on validation."""

    def __init__(self, name: str, train: list[Experiment], validation: list[Experiment], fit: PhysicsEstimate,
                 baseline: ModelScore, rule: SelectionRule, initial_state: str, max_nfev: int, template: Budget):
        self.name, self.train, self.validation, self.fit, self.baseline = name, train, validation, fit, baseline
        self.rule, self.initial_state, self.max_nfev, self.template = rule, initial_state, max_nfev, template
        self.ftol = REFIT_CRITERION_STEP / sum(r.y.numel() for r in train)

    def budget(self, effect: str) -> Budget:
        """A fresh budget for the refit of ``effect``, with the rung's limits."""
        return self.template.restarted(f"refitting {self.name} + {effect}")

    def run(self, entry: EffectEvidence, extended, strength: str, move: torch.Tensor,
            bounds: dict[str, tuple[float, float]]) -> None:
        """Refit ``entry``'s model and record in ``entry`` the result, the failure, or that it is undecided."""
        budget = self.budget(entry.effect)
        if budget.expired:
            entry.undecided, entry.refit_reason = 0.0, "undecided: the diagnosis' budget was spent before its refit"
            return
        log.info("refitting %s + %s", self.name, entry.effect)
        try:
            refit = refit_effect(extended, strength, entry.first_order_strength, self.train, self.max_nfev,
                                 self.initial_state, self.fit, move, self.ftol, budget, bounds)
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
        entry.refit = score_model(extended, refit, self.validation, self.rule, self.initial_state)
        entry.improvement = self.baseline.criterion - entry.refit.criterion
        entry.unphysical = unphysical_values(entry.refit.rows())


def rank_missing_effects(
    physics,
    candidates: Sequence[AbstractEffect],
    train: Experiment | Sequence[Experiment],
    validation: Experiment | Sequence[Experiment],
    *,
    rule: SelectionRule | None = None,
    shortlist: int = 2,
    initial_state: Literal["rest", "estimate"] = "rest",
    start_states: Sequence[torch.Tensor] | None = None,
    probe: float = 1e-4,
    max_nfev: int = 40,
    refit_budget: float = REFIT_BUDGET,
    deadline: float | None = None,
    solver: Solver | None = None,
) -> Ranking:
    """Rank ``candidates`` as the effect missing from ``physics`` (module docstring).

    Args:
        physics: the physics to diagnose (not modified: a copy is fitted). Its learnable parameters
            are fitted; ``physics + effect`` must work for every candidate.
        candidates: effects at zero strength, e.g. :func:`~torchpaml._physics.default_effects`; none: the
            fitted baseline alone.
        train: the records to fit on.
        validation: the records to rank on.
        rule: the decision rule (:class:`~torchpaml._diagnostics.SelectionRule`; default BIC, threshold 10,
            min_share 5 %).
        shortlist: how many of the best-scored candidates are refitted (``len(candidates)``: all).
        initial_state: ``"rest"``, or ``"estimate"``: every fit estimates each training record's initial
            state (:func:`~torchpaml._fit.fit_physics`), and each validation record starts from its best state.
        start_states: with ``"estimate"``, the baseline fit's starting guesses of the training records' initial
            states (default rest).
        probe: strength $\\delta$ of the first-order secant.
        max_nfev: iteration limit of each refit.
        refit_budget: each refit may take this many times the rung's own fit in seconds, or this many times
            ``max_nfev`` evaluations at the refit's own cost per evaluation, whichever is longer
            (:mod:`torchpaml._budget`); one over it is reported undecided (``EffectEvidence.undecided``).
        deadline: a ``time.perf_counter()`` time by which every refit must end (the diagnosis' ``budget``).
        solver: the solver ``physics`` was last fitted with (``PhysicsEstimate.solver``), where the step checks of
            its fits start (:func:`~torchpaml._simulate.solvers.continued`); default ``Auto()``.
    """
    train, validation = as_records(train), as_records(validation)
    names = [c.name for c in candidates]
    if len(set(names)) != len(names):
        raise ConfigurationError(f"candidate effects must have distinct names, got {names}")
    present = set(getattr(physics, "effects", {}))
    if present & set(names):
        raise ConfigurationError(f"candidate(s) {sorted(present & set(names))} are already in {physics.display_name}; "
                         "drop them from the candidates")
    base_model = getattr(physics, "base", physics)
    skipped = {c.name: reason for c in candidates if (reason := c.applies_to(base_model)) is not None}
    candidates = [c for c in candidates if c.name not in skipped]
    if skipped and not candidates:  # checked before any fit
        raise ConfigurationError(f"none of the candidate effects applies to {physics.display_name}: "
                         + "; ".join(f"{name}: {reason}" for name, reason in skipped.items())
                         + ". Give candidates written for this physics (`candidates:` in a --config file)")
    base = copy.deepcopy(physics)
    log.info("fitting %s on %d samples", base.display_name, sum(len(r.t) for r in train))
    began = time.perf_counter()
    fit = fit_physics(base, train, max_nfev=max_nfev, initial_state=initial_state, start_states=start_states,
                      solver=continued(solver))
    seconds = time.perf_counter() - began
    rule = rule or SelectionRule()
    baseline = score_model(base, fit, validation, rule, initial_state)
    if not candidates:
        return Ranking(baseline, [], rule, skipped, initial_state)
    scale = float(torch.sqrt(sum(torch.sum(r.y**2) for r in train)))
    log.info("scoring %d candidates to first order", len(candidates))
    engines = _Engines(base, train, fit, scale)
    entries, extended_models = [], {}
    for candidate in candidates:
        strength = f"{candidate.name}.{candidate.strength}"
        engine, reference = engines.of(candidate)
        delta = candidate.probe(train) or probe
        best, failure = None, None
        for setting, extended in _by_promise(base, candidate, train, fit, delta, reference, engine, scale):
            try:
                best = extended, _first_order(extended, strength, fit, scale, delta, reference, engine)
                break
            except SimulationError as error:  # its own states blow up at zero strength: a stiff start
                failure = f"not scored: the model blows up at zero strength from {setting or 'its defaults'}: {error}"
        if best is None:
            entries.append(EffectEvidence(candidate.name, candidate.equation, 0.0, 1, 0.0, failure=failure,
                                          refit_reason="not refitted: not scored"))
            continue
        extended, (score, order, start, move) = best
        entries.append(EffectEvidence(candidate.name, candidate.equation, score, order, start))
        bounds = {f"{candidate.name}.{name}": limits for name, limits in candidate.bounds(train).items()
                  if f"{candidate.name}.{name}" in extended.learnable_names()}
        extended_models[candidate.name] = (extended, strength, move, bounds)
    by_score = sorted(entries, key=lambda e: -e.score)
    refits = _Refits(base.display_name, train, validation, fit, baseline, rule, initial_state, max_nfev,
                     Budget(base.display_name, refit_budget * seconds, refit_budget * max_nfev,
                            math.inf if deadline is None else deadline))
    for rank, entry in enumerate(e for e in by_score if e.effect in extended_models):
        why_not = f"outside the shortlist of the {shortlist} best scores" if rank >= shortlist else \
            _cannot_pass(entry.score, rule, validation, extended_models[entry.effect][0], base)
        if why_not is not None:
            entry.refit_reason = f"not refitted: {why_not}"
            continue
        entry.refit_reason = f"refitted: score rank {rank + 1} of the shortlist of {shortlist}, and it could pass the rule"
        refits.run(entry, *extended_models[entry.effect])
    refitted = sorted((e for e in entries if e.refit is not None), key=lambda e: e.refit.criterion)
    if refitted:  # the best may ask for another shape (freeing only improves it, so it stays first)
        best = refitted[0]
        _free_shape(best, train, validation, rule, max_nfev, initial_state, refits.ftol, refits.budget(best.effect),
                    extended_models[best.effect][3])
        best.improvement = baseline.criterion - best.refit.criterion
        best.unphysical = unphysical_values(best.refit.rows())
    rest = [e for e in by_score if e.refit is None]
    return Ranking(baseline, refitted + rest, rule, skipped, initial_state)
