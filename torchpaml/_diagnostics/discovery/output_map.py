r"""The closed form of what the output map misses, $y = h(x, u) + \sum_i c_i\,\theta_i(x, u)$, found as discovery
finds a force: by sparse regression on a library of terms, then refitted with the physics.

On a fitted model's training trajectories $x(t)$ (each record from its estimated or resting initial state), the
output residual $r = y - h(x, u)$ is measured directly: no network has to learn it, as a missing rate must be learned
through the dynamics. The terms $\theta_i$ of the :class:`~torchpaml.TermLibrary` over the physics' variables (the
smoothed signs left out: their widths are not regressed) are evaluated along $x(t)$, scaled to unit norm, and the
:class:`~torchpaml.SparseRegression` chooses the support of lowest extended BIC. The support's least-squares
coefficients start a :class:`~torchpaml.DiscoveredForce` whose terms add to the output (its equation
``"output"``), refitted with the physics' own parameters on the training records and scored on validation. A
residual that is dynamics, not an output map, leaves the regression little to explain or the refit little gain;
the validation score says which.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Sequence

import torch

from torchpaml._budget import Budget
from torchpaml._data import Record
from torchpaml._data.simulation import record_states
from torchpaml._diagnostics.ranking.scoring import score_model
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._diagnostics.results import ModelScore
from torchpaml._fit.initial_state import InitialState
from torchpaml._fit.physics_fit import fit_physics
from torchpaml._fit.sparse_regression import SparseRegression
from torchpaml._physics.discovered import OUTPUT, DiscoveredForce
from torchpaml._simulate.solvers import Auto
from torchpaml._physics.terms import TermLibrary, compile_term, input_values, state_columns, variables_of

__all__ = ["NAME", "output_closed_form"]

log = logging.getLogger(__name__)

#: The name of the discovered output terms in the extended model.
NAME = "output_closed_form"


def output_closed_form(score: ModelScore, train: Sequence[Record], validation: Sequence[Record], rule: SelectionRule,
                       initial_state: InitialState, *, library: TermLibrary = TermLibrary(),
                       regression: SparseRegression = SparseRegression(), max_nfev: int = 40,
                       budget: Budget | None = None) -> ModelScore | None:
    """The fitted model of ``score`` with the closed form of its output map's residual (module docstring), refitted
    on ``train`` and scored on ``validation``; ``None`` where the physics has several outputs or the regression keeps
    no term."""
    physics = score.model
    if physics.output_dim != 1:
        return None
    variables, _ = variables_of(physics)
    compiled = [c for c in (compile_term(t, variables) for t in library.build(physics)) if not c.widths]
    terms = [c.text for c in compiled]
    columns, residual = [], []
    with torch.no_grad():
        for record, x0 in zip(train, score.train_states, strict=True):
            states = record_states(physics, record, x0, solver=score.solver)
            residual.append((record.y - physics.output(states, record.u))[:, 0])
            values = {name: states[:, i] for name, i in state_columns(physics).items()}
            values.update(input_values(physics, record.u))
            columns.append(torch.stack([c.evaluate(values) * torch.ones_like(states[:, 0]) for c in compiled], dim=1))
    A, r = torch.cat(columns), torch.cat(residual)
    norms = A.norm(dim=0)
    usable = norms > 0
    A, terms, norms = A[:, usable] / norms[usable], [t for t, keep in zip(terms, usable.tolist()) if keep], norms[usable]
    support = regression.select(A, r)
    if not support:
        log.info("output map: the sparse regression kept no term")
        return None
    coefficients = torch.linalg.lstsq(A[:, support], r[:, None]).solution[:, 0] / norms[support]
    scored = _refit(score, [terms[i] for i in support], coefficients.tolist(), train, validation, rule,
                    initial_state, max_nfev, budget)
    effect = scored.model.effects[NAME]
    values = effect.values()
    kept = [(term, values[name]) for term, name in zip(effect.terms, effect.parameter_names, strict=True)
            if abs(values[name]) >= regression.min_t * scored.uncertainty.get(f"{NAME}.{name}", float("inf"))]
    if not kept or len(kept) == len(effect.terms):
        return scored if kept else None
    log.info("output map: %d of %d terms determined by the refit; refitting those", len(kept), len(effect.terms))
    return _refit(score, [t for t, _ in kept], [c for _, c in kept], train, validation, rule, initial_state,
                  max_nfev, budget)


def _refit(score: ModelScore, terms: list[str], coefficients: list[float], train: Sequence[Record],
           validation: Sequence[Record], rule: SelectionRule, initial_state: InitialState, max_nfev: int,
           budget: Budget | None) -> ModelScore:
    """``score``'s model plus the output ``terms`` from ``coefficients``, refitted from its parameters and states on
    ``train`` and scored on ``validation``."""
    physics = score.model
    effect = DiscoveredForce(terms, coefficients, equations=[OUTPUT] * len(terms))
    effect.name = NAME
    extended = copy.deepcopy(physics) + effect
    log.info("output map: refitting %s with %s", physics.display_name, effect.expression())
    fit = fit_physics(extended, list(train), max_nfev=max_nfev, initial_state=initial_state,
                      start_states=initial_state.carried(score.train_states), solver=Auto(start=score.solver),
                      budget=None if budget is None else budget.restarted(f"refitting {extended.display_name}"))
    return score_model(extended, fit, list(validation), rule, initial_state)
