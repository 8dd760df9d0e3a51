r"""The model ladder: physics -> physics + best effect -> ... until no candidate helps significantly.

Each rung runs the ranker (:class:`~torchpaml.Ranker`, :func:`~torchpaml.rank_missing_effects`) on
the current model with the candidates not yet added (and that apply). If it recommends an effect (its criterion beats the current
model's by more than the threshold, its validation mismatch falls by at least ``min_share``, and its
parameters are physical), the refitted model, fitted once more to the last digits, becomes the next
rung; otherwise the ladder stops. After a rung that adds an effect, each earlier effect is tried out of its model
(:mod:`~torchpaml._diagnostics.ranking.removal`): one the rule lets go is removed, and the ladder goes on without it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import torch

from torchpaml._data import Record
from torchpaml._diagnostics.ranking.ranker import Ranker
from torchpaml._diagnostics.ranking.removal import Removal, remove_stand_in
from torchpaml._diagnostics.ranking.steps import placed
from torchpaml._diagnostics.results import ModelScore, Ranking
from torchpaml._diagnostics.ranking.scoring import as_records
from torchpaml._fit.initial_state import InitialState, Rest, as_initial_state
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effects import AbstractEffect

__all__ = ["Ladder", "model_ladder"]


@dataclass
class Ladder:
    """``steps[0]`` is the fitted physics, ``steps[i]`` the model after the i-th added effect (``added[i - 1]``),
    without the earlier effect ``removed[i - 1]`` where one was removed there (else ``None``).

    ``rankings[i]`` is the ranking made on ``steps[i]`` (whose ``baseline`` it is); the last one recommended
    nothing, or had no candidate left, or ``max_steps`` was reached. ``removals``: every earlier effect tried out
    of a rung's model (:class:`~torchpaml._diagnostics.ranking.removal.Removal`).
    """

    steps: list[ModelScore]
    added: list[str]
    rankings: list[Ranking]
    removed: list[str | None] = field(default_factory=list)
    removals: list[Removal] = field(default_factory=list)

    @property
    def final(self) -> ModelScore:
        return self.steps[-1]

    @property
    def found(self) -> list[str]:
        """The final model's effects, in the order the ladder added them: ``added`` without ``removed``."""
        gone = set(self.removed) - {None}
        return [name for name in self.added if name not in gone]


def model_ladder(
    physics: AbstractPhysics,
    candidates: Sequence[AbstractEffect],
    train: Record | Sequence[Record],
    validation: Record | Sequence[Record],
    *,
    ranker: Ranker = Ranker(),
    initial_state: str | InitialState = Rest(),
    start_states: Sequence[torch.Tensor] | None = None,
    deadline: float | None = None,
    max_steps: int | None = None,
) -> Ladder:
    """Climb the ladder (module docstring), each rung ranked by ``ranker`` (:class:`~torchpaml.Ranker`) from the
    records' initial states as ``initial_state`` says (:class:`~torchpaml.Rest`, :class:`~torchpaml.Estimate`).

    ``start_states``: with ``Estimate()``, the first rung's starting guesses of the training records' initial states
    (each next rung starts from its refit's). ``deadline``: a ``time.perf_counter()`` time by which every refit
    ends. ``max_steps`` bounds the number of effects added (default: as many as keep helping).
    """
    train, validation = as_records(train), as_records(validation)
    initial_state = as_initial_state(initial_state)
    candidates = placed(physics, candidates)  # a force on each degree of freedom: each rung's candidates by name
    ranking = ranker.rank(physics, candidates, train, validation, initial_state=initial_state,
                          start_states=start_states, deadline=deadline)
    ladder = Ladder([ranking.baseline], [], [ranking])
    while ranking.recommended is not None and (max_steps is None or len(ladder.added) < max_steps):
        best = ranking.recommended
        ladder.added.append(best.effect)
        remaining = [e.effect for e in ranking.entries if e.effect != best.effect]
        # the next rung's baseline is the refit's model fitted to the last digits (the refit stopped early)
        ranking = ranker.rank(best.refit.model, [c for c in candidates if c.name in remaining], train, validation,
                              initial_state=initial_state,
                              start_states=initial_state.carried(best.refit.train_states),
                              deadline=deadline, solver=best.refit.solver, refitted=best)
        reduced, tried = remove_stand_in(ranking.baseline, ladder.found[:-1], len(ladder.steps), train, validation,
                                         ranking.rule, initial_state, ranker.max_nfev, deadline)
        ladder.removals.extend(tried)
        ladder.removed.append(None if reduced is None else tried[-1].effect)
        if reduced is not None:
            ranking = ranker.rank(reduced.model, [c for c in candidates if c.name in remaining], train, validation,
                                  initial_state=initial_state, start_states=initial_state.carried(reduced.train_states),
                                  deadline=deadline, solver=reduced.solver)
        ladder.steps.append(ranking.baseline)
        ladder.rankings.append(ranking)
    return ladder
