r"""Beyond the greedy ladder: after each rung, each earlier effect is tried out of the model.

A greedy ladder keeps what it added: an effect taken on an early rung as a stand-in for one that only a later rung
finds stays in the model. So after each rung that adds an effect, the rung's model $M = P + e_1 + \dots + e_k$
(fitted to the last digits) is compared with $M \setminus e_j$ for each earlier effect $e_j$, $j < k$, in the
ladder's order: the model without it, refitted on the training records from $M$'s values and scored on validation.
$e_j$ stays only where $M$ beats $M \setminus e_j$ by the selection rule itself (its criterion lower by more than
the threshold, its validation mismatch lower by at least ``min_share``; $e_j$'s own states charged as parameters,
:meth:`~torchpaml.SelectionRule.why_not`). The first effect the rule lets go is removed; the ladder goes on from the
model without it, and that effect is no candidate again. Every try is reported (:class:`Removal`): in
``Ladder.removals`` and ``diagnosis.json``'s ``removals``.
"""

from __future__ import annotations

import copy
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from torchpaml._budget import Budget, OverBudget
from torchpaml._data import Record
from torchpaml._diagnostics.ranking.refits import effect_bounds
from torchpaml._diagnostics.ranking.scoring import score_model
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._diagnostics.results import ModelScore
from torchpaml._errors import SimulationError
from torchpaml._fit.initial_state import InitialState
from torchpaml._fit.physics_fit import fit_physics
from torchpaml._simulate.solvers import Auto

__all__ = ["Removal", "remove_stand_in", "without"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Removal:
    """One earlier effect tried out of a rung's model.

    Attributes:
        rung: the ladder's step (index into ``Ladder.steps``) whose model it was tried out of.
        effect: the effect tried out.
        nrmse_validation, criterion: the model without it, refitted, on validation; ``None`` where its refit failed.
        removed: the rule let it go, and the ladder went on without it.
        reason: why, in one sentence.
        against: the validation mismatch of the model it was tried out of.
        score: the model without it, refitted and scored (``None`` where its refit failed).
    """

    rung: int
    effect: str
    nrmse_validation: float | None
    criterion: float | None
    removed: bool
    reason: str
    against: float
    score: ModelScore | None = field(default=None, repr=False)


def without(model, name: str):
    """A copy of the composed ``model`` without its effect ``name``, the others in their order with their values."""
    copied = copy.deepcopy(model)
    reduced = copied.without_effects()
    for effect_name, effect in copied.effects.items():
        if effect_name != name:
            reduced = reduced + effect
    return reduced


def remove_stand_in(current: ModelScore, earlier: Sequence[str], rung: int, train: list[Record],
                    validation: list[Record], rule: SelectionRule, initial_state: InitialState, max_nfev: int,
                    deadline: float | None) -> tuple[ModelScore | None, list[Removal]]:
    """Try each of ``earlier`` (effects of ``current``'s model, in the ladder's order) out of it (module docstring):
    the refitted model without the first effect the rule lets go (``None`` where it keeps them all), and every try."""
    tried = []
    for name in earlier:
        reduced = without(current.model, name)
        own = len(current.model.effects[name].own_states)
        base_states = reduced.without_effects().state_dim
        starts = initial_state.carried([x.reshape(-1)[:base_states] for x in current.train_states])
        label = f"removing {name} from {current.name}"
        log.info("%s (a stand-in, where the rule does not keep it)", label)
        try:
            fit = fit_physics(reduced, train, max_nfev=max_nfev, initial_state=initial_state, start_states=starts,
                              solver=Auto(start=current.solver), bounds=effect_bounds(reduced, train),
                              budget=Budget(label, deadline=math.inf if deadline is None else deadline))
            score = score_model(reduced, fit, validation, rule, initial_state)
        except (SimulationError, OverBudget) as error:
            tried.append(Removal(rung, name, None, None, False, f"kept: the model without it did not refit ({error})",
                                 current.nrmse_validation))
            continue
        why = rule.why_not(score, current, extra=own)
        if why is None:
            tried.append(Removal(rung, name, score.nrmse_validation, score.criterion, False,
                                 f"kept: {current.name} beats the model without it by the rule",
                                 current.nrmse_validation, score))
            continue
        tried.append(Removal(rung, name, score.nrmse_validation, score.criterion, True,
                             f"removed: against the model without it, {current.name} is not better by the rule ({why}); "
                             f"{name} stood in for what the later effects explain", current.nrmse_validation, score))
        return score, tried
    return None, tried
