r"""The closed form refitted with the physics, with honest numbers (step 3 of :mod:`~torchpaml._diagnostics.discovery.result`).

:func:`refit_closed_form` fits ``physics + DiscoveredForce(terms)`` by output error, then, pass by pass:

* a smoothed sign's width is bounded to what the record resolves (:func:`~torchpaml._diagnostics.discovery.regressors.width_range`);
  one that ends within :data:`EDGE` of the lower edge is a sign (``tanh(s/eps)`` becomes ``sign(s)``, and
  ``s*sign(s)`` becomes ``Abs(s)``), one at the upper edge is linear (``m*tanh(s/eps)`` becomes ``m*s``);
* the term whose standard error most exceeds its coefficient (more than :data:`DETERMINED` times) is
  dropped: the records do not determine it (a term the physics already has, or one of a collinear group);
* terms whose contribution is below :data:`PRUNE` of the largest are dropped, unless that costs more than
  the rule's threshold of the criterion;

and refits what is left, each reduced support from its own first-order coefficients.
"""

from __future__ import annotations

import copy
import math
import warnings
from collections.abc import Callable, Sequence

import sympy
import torch

from torchpaml._fit.initial_state import InitialState
from torchpaml._physics.base import AbstractPhysics
from torchpaml._data import Record
from torchpaml._diagnostics.ranking.refits import REFIT_CRITERION_STEP, refit_effect
from torchpaml._diagnostics.results import ModelScore
from torchpaml._diagnostics.ranking.scoring import score_model
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._errors import SimulationError
from torchpaml._fit import PhysicsEstimate
from torchpaml._budget import Budget
from torchpaml._fit.uncertainty import IdentifiabilityWarning
from torchpaml._physics.discovered import DiscoveredForce
from torchpaml._physics.term_parser import parse_term
from torchpaml._physics.terms import compile_term, input_values, state_columns, width_symbol
from torchpaml._data.simulation import record_states
from torchpaml._simulate.solvers import Solver

__all__ = ["fit_closed_form", "refit_closed_form"]

#: A term of the refitted closed form whose contribution is below this share of the largest term's is dropped.
PRUNE = 0.05
#: A width within this factor of an edge of its range has reached the edge (its limit replaces it).
EDGE = 1.05
#: Largest standard error, relative to the coefficient, of a term that the records determine (a t-statistic of 1).
DETERMINED = 1.0


def _limit(term: str, width: str, variable: str, edge: str) -> str:
    r"""``term`` with ``tanh(variable/width)`` replaced by its limit at the ``"low"`` edge (a sign, and
    $s\,\mathrm{sign}(s) = |s|$) or the ``"high"`` edge (``variable/width``, the width then folded into the
    coefficient)."""
    s, w = sympy.Symbol(variable, real=True), sympy.Symbol(width, real=True)
    expression = parse_term(compile_term(term, None).text)
    sign = sympy.tanh(s / w)
    if edge == "high":
        return str(expression.subs(sign, s))
    power = expression.subs(sign, 1).as_powers_dict().get(s, 0)
    return str(expression.subs(sign, sympy.Abs(s) / s if power >= 1 else sympy.sign(s)))


def fit_closed_form(physics: AbstractPhysics, pairs: list[tuple[str, str]], coefficients: list[float],
                    widths: dict[str, tuple[float, float]], train: Sequence[Record], max_nfev: int,
                    initial_state: InitialState,
                    budget: Budget | None = None, solver: Solver | None = None
                    ) -> tuple[torch.nn.Module, PhysicsEstimate] | None:
    """``physics + DiscoveredForce(pairs)`` from ``coefficients`` (widths from twice their lower bound, bounded to
    their ranges) fitted with the physics by output error, and its estimate; ``None`` where it blows up. Past
    ``budget``, :class:`~torchpaml.OverBudget`. ``solver``: the one ``physics`` was fitted with."""
    terms = [t for _, t in pairs]
    used = sorted({w for t in terms for w in compile_term(t, None).widths})
    effect = DiscoveredForce(terms, coefficients, [e for e, _ in pairs], widths={w: 2 * widths[w][0] for w in used})
    extended = copy.deepcopy(physics) + effect
    for w in used:
        extended.bound(f"discovered.{w}", *widths[w])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            estimate = refit_effect(extended, "discovered.gain", 1.0, train, max_nfev, initial_state,
                                    ftol=REFIT_CRITERION_STEP / sum(r.y.numel() for r in train), budget=budget,
                                    solver=solver)
    except SimulationError:
        return None
    return extended, estimate


def refit_closed_form(physics: AbstractPhysics, pairs: list[tuple[str, str]], coefficients: list[float],
                      widths: dict[str, tuple[float, float]],
           train: Sequence[Record], validation: Sequence[Record], rule: SelectionRule,
           max_nfev: int, initial_state: InitialState, first_order: Callable[[list[tuple[str, str]]], list[float] | None],
           budget: Budget | None = None, solver: Solver | None = None) -> ModelScore | None:
    """``physics + DiscoveredForce(pairs)`` refitted and scored, with honest numbers (module docstring, step 3);
    ``None`` when no term survives or it blows up. Each reduced support starts from its own first-order coefficients
    (``first_order``), not from the previous refit's, whose collinear terms carry no information. Every refit shares
    ``budget`` (:class:`~torchpaml.OverBudget` past it); ``solver``: the one ``physics`` was fitted with."""
    index = state_columns(physics)
    owner = {width_symbol(s): s for s in index}

    def refit(kept: list[tuple[str, str]], start: list[float]) -> ModelScore | None:
        fitted = fit_closed_form(physics, kept, start, widths, train, max_nfev, initial_state, budget, solver)
        try:
            return None if fitted is None else score_model(*fitted, validation, rule, initial_state)
        except SimulationError:  # it blows up on the validation records (or their initial states' fit)
            return None

    score = refit(pairs, coefficients)
    for _ in range(8):  # each pass removes or replaces at least one term, or stops
        if score is None:
            return None
        effect = score.model.effects["discovered"]
        values = effect.values()
        current = list(zip(effect.equations, effect.terms, strict=True))
        starts = [values[n] for n in effect.parameter_names]
        changed = False
        for w in effect.width_names:  # a width at an edge of its range: its limit replaces it
            low, high = widths[w]
            edge = "low" if values[w] < EDGE * low else "high" if values[w] > high / EDGE else None
            if edge is not None:
                scale = 1.0 if edge == "low" else 1 / values[w]
                for i, (e, t) in enumerate(current):
                    if w in compile_term(t, None).widths:
                        current[i] = (e, _limit(t, w, owner[w], edge))
                        starts[i] *= scale
                changed = True
        relative = [score.uncertainty.get(f"discovered.{n}", math.inf) / max(abs(values[n]), 1e-300)
                    for n in effect.parameter_names]
        relative = [r if math.isfinite(r) else math.inf for r in relative]
        sizes = _sizes(score, train)
        worst = max(range(len(relative)), key=lambda i: (relative[i], -sizes[i]))
        determined = [relative[i] < DETERMINED or i != worst for i in range(len(relative))]  # drop the worst only
        keep = [i for i in range(len(current))
                if determined[i] and sizes[i] >= PRUNE * max(sizes) and 1e-12 < abs(starts[i]) < 1e12]
        merged: dict[tuple[str, str], float] = {}
        for i in keep:  # a limit may turn two terms into one: their coefficients add
            merged[current[i]] = merged.get(current[i], 0.0) + starts[i]
        if not changed and len(merged) == len(current):
            return score
        if not merged:
            return None
        candidate = refit(list(merged), first_order(list(merged)) or list(merged.values()))
        if candidate is None:
            return score if all(determined) else None
        if all(determined) and not changed and candidate.criterion > score.criterion + rule.threshold:
            return score  # the pruning cost more than the threshold: the small terms stay
        score = candidate
    return score


def _sizes(score: ModelScore, train: Sequence[Record]) -> list[float]:
    """Each discovered term's contribution, $|g c_i|$ times the RMS of $\theta_i$, along the refitted model's first
    training trajectory."""
    model = score.model
    effect = model.effects["discovered"]
    record = train[0]
    index = state_columns(model)
    states = record_states(model, record, score.train_states[0], score.solver)
    with torch.no_grad():
        values = {**{name: states[:, i] for name, i in index.items()}, **input_values(model, record.u),
                  **{w: getattr(effect, w) for w in effect.width_names}}
        return [abs(float(effect.gain * getattr(effect, name))) * float(compile_term(term, None).evaluate(values)
                                                                         .square().mean().sqrt())
                for name, term in zip(effect.parameter_names, effect.terms, strict=True)]
