r"""The model ladder: physics -> physics + best effect -> ... until no candidate helps significantly.

Each rung runs the ranker (:class:`~torchpaml.Ranker`, :func:`~torchpaml.rank_missing_effects`) on
the current model with the candidates not yet added (and that apply). If it recommends an effect (its criterion beats the current
model's by more than the threshold, its validation mismatch falls by at least ``min_share``, and its
parameters are physical), the refitted model, fitted once more to the last digits, becomes the next
rung; otherwise the ladder stops. After a rung that adds an effect, each earlier effect is tried out of its model
(:mod:`~torchpaml._diagnostics.ranking.removal`): one the rule lets go is removed, and the ladder goes on without it.
Up to ``beam`` models climb side by side, the runner-up candidates on their own paths, and validation chooses among
where they end (:mod:`~torchpaml._diagnostics.ranking.beam`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch

from torchpaml._data import Record
from torchpaml._diagnostics.ranking.beam import BeamEnd, chosen_end, left_behind, next_beam, proposals
from torchpaml._diagnostics.ranking.ranker import Ranker
from torchpaml._diagnostics.ranking.removal import Removal, remove_stand_in
from torchpaml._diagnostics.ranking.steps import placed
from torchpaml._diagnostics.results import ModelScore, Ranking
from torchpaml._diagnostics.ranking.scoring import as_records
from torchpaml._fit.initial_state import InitialState, Rest, as_initial_state
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effects import AbstractEffect

__all__ = ["Ladder", "model_ladder"]

log = logging.getLogger(__name__)


@dataclass
class Ladder:
    """``steps[0]`` is the fitted physics, ``steps[i]`` the model after the i-th added effect (``added[i - 1]``),
    without the earlier effect ``removed[i - 1]`` where one was removed there (else ``None``).

    ``rankings[i]`` is the ranking made on ``steps[i]`` (whose ``baseline`` it is); the last one recommended
    nothing, or had no candidate left, or ``max_steps`` was reached. ``removals``: every earlier effect tried out
    of a rung's model (:class:`~torchpaml._diagnostics.ranking.removal.Removal`). ``beam``: where each model of the
    beam ended, this ladder's path among them (:class:`~torchpaml._diagnostics.ranking.beam.BeamEnd`); the fields
    above are the chosen path's.
    """

    steps: list[ModelScore]
    added: list[str]
    rankings: list[Ranking]
    removed: list[str | None] = field(default_factory=list)
    removals: list[Removal] = field(default_factory=list)
    beam: list[BeamEnd] = field(default_factory=list)

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
    ends. ``max_steps`` bounds the number of effects added (default: as many as keep helping). ``ranker.beam`` models
    climb per rung (:mod:`~torchpaml._diagnostics.ranking.beam`; 1: the greedy ladder). The ladder returned is the
    chosen end's path; ``Ladder.beam`` holds every end.
    """
    beam = ranker.beam
    train, validation = as_records(train), as_records(validation)
    initial_state = as_initial_state(initial_state)
    candidates = placed(physics, candidates)  # a force on each degree of freedom: each rung's candidates by name
    climb = _Climb(ranker, candidates, train, validation, initial_state, deadline)
    ranking = ranker.rank(physics, candidates, train, validation, initial_state=initial_state,
                          start_states=start_states, deadline=deadline)
    paths, greedy, ended, behind, seen = [Ladder([ranking.baseline], [], [ranking])], 0, [], [], {frozenset()}
    while paths:
        offers = []
        for place, path in enumerate(paths):
            full = max_steps is not None and len(path.added) >= max_steps
            offered = [] if full else proposals(path.rankings[-1], beam)
            if not offered:
                ended.append((path, place == greedy))
            offers += [(place, entry, frozenset([*path.found, entry.effect])) for entry in offered]
        lead = next((offer for offer in offers if offer[0] == greedy), None)
        climbing = next_beam(lead, [offer for offer in offers if offer is not lead], seen, beam, ranker.rule)
        outrun = {place for place, _, _ in offers} - {place for place, _ in climbing}
        behind += [left_behind(tuple(paths[place].found), paths[place].final, ranker.rule, "its proposals lost the "
                               "beam's places to better-scored ones, or are models the beam already holds")
                   for place in sorted(outrun)]
        next_paths, greedy = [], None
        for place, entry in climbing:
            is_greedy = lead is not None and entry is lead[1]
            if not is_greedy:
                log.info("beam: also climbing from %s + %s (validation %.3g %%)", paths[place].final.name,
                         entry.effect, 100 * entry.refit.nrmse_validation)
            path = climb(paths[place], entry)
            if not is_greedy and path.removed[-1] is not None and frozenset(path.found) in seen:
                log.info("beam: %s is a model the beam already climbed from; this path stops", path.final.name)
                behind.append(left_behind(tuple(path.found), path.final, ranker.rule, "a removal made it a model the "
                                          "beam had already climbed from"))
                continue
            seen.add(frozenset(path.found))
            greedy = len(next_paths) if is_greedy else greedy
            next_paths.append(path)
        paths = next_paths
    choice, ends = chosen_end([(tuple(path.found), path.final, is_greedy) for path, is_greedy in ended], ranker.rule)
    ladder = ended[choice][0]
    ladder.beam = ends + behind
    return ladder


@dataclass(frozen=True)
class _Climb:
    """One rung up from a path: the settings every rung of one ladder shares."""

    ranker: Ranker
    candidates: list[AbstractEffect]
    train: list[Record]
    validation: list[Record]
    initial_state: InitialState
    deadline: float | None

    def __call__(self, path: Ladder, best) -> Ladder:
        """``path`` with the next rung: ``best`` (an entry of its last ranking) added, the next rung's baseline its
        refit's model fitted to the last digits, then each earlier effect tried out (module docstring)."""
        ranker, train, validation, initial_state = self.ranker, self.train, self.validation, self.initial_state
        remaining = [e.effect for e in path.rankings[-1].entries if e.effect != best.effect]
        left = [c for c in self.candidates if c.name in remaining]
        ranking = ranker.rank(best.refit.model, left, train, validation, initial_state=initial_state,
                              start_states=initial_state.carried(best.refit.train_states),
                              deadline=self.deadline, solver=best.refit.solver, refitted=best)
        found = [*path.found, best.effect]
        reduced, tried = remove_stand_in(ranking.baseline, found[:-1], len(path.steps), train, validation,
                                         ranking.rule, initial_state, ranker.max_nfev, self.deadline)
        if reduced is not None:
            ranking = ranker.rank(reduced.model, left, train, validation, initial_state=initial_state,
                                  start_states=initial_state.carried(reduced.train_states), deadline=self.deadline,
                                  solver=reduced.solver)
        return Ladder([*path.steps, ranking.baseline], [*path.added, best.effect], [*path.rankings, ranking],
                      [*path.removed, None if reduced is None else tried[-1].effect], [*path.removals, *tried])
