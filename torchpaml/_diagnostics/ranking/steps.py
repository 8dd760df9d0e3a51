r"""Which effect is missing: rank candidate effects by a first-order score, then by refitted validation error.

1. **Baseline.** The physics' learnable parameters are fitted to the training records
   (:func:`~torchpaml.fit_physics`), leaving the residual
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
   the best of them has shape parameters (:attr:`~torchpaml.AbstractEffect.shape`: the
   width of Coulomb friction's smoothed sign), it is refitted once more with them freed, and that
   refit is kept when it lowers the criterion by more than ``threshold``: the data asks for another shape.
   A refit whose optimum fails the step check (:mod:`torchpaml._fit.resolution`: its output depends on
   the RK4 step beyond what substeps resolve) has no result; its evidence says why (``failure``).
4. **Rank** by the information criterion on the validation records (:class:`~torchpaml.SelectionRule`:
   BIC or AIC). The best candidate is *recommended* when the rule accepts it over the baseline
   (criterion lower by more than ``threshold``, validation mismatch lower by ``min_share``, training
   mismatch not higher) and
   - its refitted parameters lie in their declared physical ranges (``physical`` of
     :class:`~torchpaml.PhysicalParameter`: a Coulomb level or a drag coefficient >= 0, a
     share of sin x in [0, 1]). An unphysical refit is flagged in its evidence and passed over.
   Among the accepted candidates, **the simpler effect wins** (:mod:`~torchpaml._diagnostics.ranking.occam`): an
   effect with its own states, or a generic one, comes first only where the rule accepts it over the best accepted
   candidate of each simpler kind, its extra states charged as parameters; where the best accepted refit is of a
   more complex kind, the best-scored candidate of each simpler kind is refitted too, so that the rule can weigh
   it. Candidates outside the shortlist follow, by score, without a refit.
"""

from __future__ import annotations


import copy
import logging
from collections.abc import Sequence

import torch

from torchpaml._budget import Budget, OverBudget
from torchpaml._data import Record
from torchpaml._metrics import sample_scales
from torchpaml._diagnostics.ranking.first_order import MIN_ACTING_SHARE, Engines, by_promise, first_order
from torchpaml._diagnostics.ranking.refits import Refits, cannot_pass, effect_bounds
from torchpaml._diagnostics.results import EffectEvidence
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._errors import ConfigurationError, SimulationError
from torchpaml._fit.initial_state import InitialState
from torchpaml._fit.physics_fit import PhysicsEstimate, fit_physics
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effects import AbstractEffect
from torchpaml._simulate.solvers import Auto, Solver

__all__ = ["applicable", "refit_shortlist", "rung_fit", "scored"]

log = logging.getLogger(__name__)


def refit_shortlist(scored: list[EffectEvidence], extended_models: dict[str, tuple], shortlist: int,
                     rule: SelectionRule, validation: list[Record], base: AbstractPhysics, refits: Refits) -> None:
    """Refit the ``shortlist`` best-scored candidates of ``scored`` that could pass ``rule`` (:func:`cannot_pass`),
    and say in each entry why it was or was not refitted; a candidate whose probe moves fewer than
    :data:`~torchpaml._diagnostics.ranking.first_order.MIN_ACTING_SHARE` of the samples is not judged by its score."""
    for entry in (e for e in scored if e.acting < MIN_ACTING_SHARE):
        entry.refit_reason = (f"not refitted: its first-order probe moves {100 * entry.acting:.2g} % of the training "
                              "samples, too few for its score to judge it (whether the fitted output reaches where it "
                              "acts is a detail of rounding); give it a start where it acts (AbstractEffect.starts: a "
                              "level inside the signal's range)")
    for rank, entry in enumerate(e for e in scored if e.acting >= MIN_ACTING_SHARE):
        why_not = f"outside the shortlist of the {shortlist} best scores" if rank >= shortlist else \
            cannot_pass(entry.score, rule, validation, extended_models[entry.effect][0], base)
        if why_not is not None:
            entry.refit_reason = f"not refitted: {why_not}"
            continue
        entry.refit_reason = (f"refitted: score rank {rank + 1} of the shortlist of {shortlist}, and it could pass "
                              "the rule")
        refits.run(entry, *extended_models[entry.effect])


def rung_fit(physics: AbstractPhysics, train: list[Record], max_nfev: int, initial_state: InitialState,
              start_states: Sequence[torch.Tensor] | None, solver: Solver | None, refitted: EffectEvidence | None,
              fit_budget: float, deadline: float) -> tuple[AbstractPhysics, PhysicsEstimate, float, float | None]:
    """A copy of ``physics`` fitted on ``train`` as the rung's baseline, its fit, the rung's fit in seconds (with the
    refit it comes from), and the seconds after which the fit stopped over its budget (``None`` where it ended).

    After a refit (``refitted``) the fit may take ``fit_budget`` times its evaluations, and over that the rung keeps the refit's
    parameters and estimate; the first rung's fit has the diagnosis' deadline, and over it the diagnosis cannot go
    on: a :class:`~torchpaml.ConfigurationError` says so."""
    base = copy.deepcopy(physics)
    label = f"fitting {base.display_name}"
    log.info("%s on %d samples", label, sum(len(r.t) for r in train))
    earlier = 0.0 if refitted is None else refitted.seconds
    budget = Budget(label, evaluations=None if refitted is None else fit_budget * refitted.refit.estimate.evaluations,
                    deadline=deadline)
    try:
        fit = fit_physics(base, train, max_nfev=max_nfev, initial_state=initial_state, start_states=start_states,
                          solver=Auto(start=solver), budget=budget, bounds=effect_bounds(base, train))
    except OverBudget as over:
        if refitted is None:
            raise ConfigurationError(f"{label} did not end within the diagnosis' budget ({over.seconds:.0f} s); give "
                                     "it more seconds (--budget, diagnose(budget=)), or shorter records") from None
        log.info("%s stopped over its budget (%.1f s): the rung keeps its refit's parameters", label, over.seconds)
        return copy.deepcopy(physics), refitted.refit.estimate, earlier + over.seconds, over.seconds
    return base, fit, earlier + budget.elapsed, None


def placed(physics: AbstractPhysics, candidates: Sequence[AbstractEffect]) -> list[AbstractEffect]:
    """The candidates with each force on every degree of freedom of ``physics``' base it may act on: one candidate
    per velocity (``coulomb_friction_v1``, ``coulomb_friction_v2``) where it has several, else as given."""
    base_model = physics.without_effects()
    return [effect for candidate in candidates for effect in candidate.placements(base_model)]


def applicable(physics: AbstractPhysics, candidates: Sequence[AbstractEffect]
                ) -> tuple[list[AbstractEffect], dict[str, str]]:
    """The candidates that apply to ``physics``, each force on every degree of freedom it may act on
    (:meth:`~torchpaml.AbstractEffect.placements`), and why each of the others does not; checked before any fit."""
    candidates = placed(physics, candidates)
    names = [c.name for c in candidates]
    if len(set(names)) != len(names):
        raise ConfigurationError(f"candidate effects must have distinct names, got {names}")
    present = set(physics.effect_names())
    if present & set(names):
        raise ConfigurationError(f"candidate(s) {sorted(present & set(names))} are already in "
                                 f"{physics.display_name}; drop them from the candidates")
    base_model = physics.without_effects()
    skipped = {c.name: reason for c in candidates if (reason := c.applies_to(base_model)) is not None}
    if skipped and len(skipped) == len(candidates):
        raise ConfigurationError(f"none of the candidate effects applies to {physics.display_name}: "
                                 + "; ".join(f"{name}: {reason}" for name, reason in skipped.items())
                                 + ". Give candidates written for this physics (`candidates:` in a --config file)")
    return [c for c in candidates if c.name not in skipped], skipped


def scored(base: AbstractPhysics, candidates: list[AbstractEffect], train: list[Record], fit: PhysicsEstimate,
            probe: float) -> tuple[list[EffectEvidence], dict[str, tuple]]:
    """Each candidate's first-order evidence, and, for each one scored, ``(base + candidate, its strength's name, the
    first-order move, its bounds)`` for its refit."""
    scale = sample_scales([r.y for r in train])  # the fit's: its residual and Jacobian are in these units
    engines = Engines(base, train, fit, scale)
    entries, extended_models = [], {}
    for candidate in candidates:
        strength = f"{candidate.name}.{candidate.strength}"
        engine, reference = engines.of(candidate)
        delta = candidate.probe(train) or probe
        best, failure = None, None
        for setting, extended in by_promise(base, candidate, train, fit, delta, reference, engine, scale):
            try:
                best = extended, first_order(extended, strength, fit, scale, delta, reference, engine)
                break
            except SimulationError as error:  # its own states blow up at zero strength: a stiff start
                failure = f"not scored: the model blows up at zero strength from {setting or 'its defaults'}: {error}"
        if best is None:
            entries.append(EffectEvidence(candidate.name, candidate.equation, 0.0, 1, 0.0, failure=failure,
                                          refit_reason="not refitted: not scored"))
            continue
        extended, (score, order, start, move, acting) = best
        entries.append(EffectEvidence(candidate.name, candidate.equation, score, order, start, acting=acting,
                                      states=len(candidate.own_states), generic=candidate.generic))
        extended_models[candidate.name] = (extended, strength, move, effect_bounds(extended, train))
    return entries, extended_models
