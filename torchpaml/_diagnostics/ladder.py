r"""The model ladder: physics -> physics + best effect -> ... until no candidate helps significantly.

Each rung runs :func:`~torchpaml._diagnostics.rank_missing_effects` on the current model with the
candidates not yet added (and that apply). If it recommends an effect (its criterion beats the current
model's by more than the threshold, its validation mismatch falls by at least ``min_share``, and its
parameters are physical), the refitted model, fitted once more to the last digits, becomes the next
rung; otherwise the ladder stops.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


from torchpaml._data import Experiment
from torchpaml._diagnostics.ranking import ModelScore, Ranking, rank_missing_effects
from torchpaml._physics.effects import AbstractEffect

__all__ = ["Ladder", "model_ladder"]


@dataclass
class Ladder:
    """``steps[0]`` is the fitted physics, ``steps[i]`` the model after the i-th added effect (``added[i - 1]``).

    ``rankings[i]`` is the ranking made on ``steps[i]`` (whose ``baseline`` it is); the last one recommended
    nothing, or had no candidate left, or ``max_steps`` was reached.
    """

    steps: list[ModelScore]
    added: list[str]
    rankings: list[Ranking]

    @property
    def final(self) -> ModelScore:
        return self.steps[-1]


def model_ladder(
    physics,
    candidates: Sequence[AbstractEffect],
    train: Experiment | Sequence[Experiment],
    validation: Experiment | Sequence[Experiment],
    *,
    max_steps: int | None = None,
    **ranking_options,
) -> Ladder:
    """Climb the ladder (module docstring); ``ranking_options`` go to :func:`rank_missing_effects` (``start_states``,
    the training records' starting guesses of the initial states, to the first rung's only).

    ``max_steps`` bounds the number of effects added (default: as many as keep helping).
    """
    first_starts = ranking_options.pop("start_states", None)  # the first rung's; each next rung starts from its refit
    ranking = rank_missing_effects(physics, candidates, train, validation, start_states=first_starts,
                                   **ranking_options)
    steps, added, rankings = [ranking.baseline], [], [ranking]
    while ranking.recommended is not None and (max_steps is None or len(added) < max_steps):
        best = ranking.recommended
        added.append(best.effect)
        remaining = [e.effect for e in ranking.entries if e.effect != best.effect]
        # the next rung's baseline is the refit's model fitted to the last digits (the refit stopped early)
        starts = best.refit.train_states if ranking_options.get("initial_state") == "estimate" else None
        ranking = rank_missing_effects(best.refit.model, [c for c in candidates if c.name in remaining], train,
                                       validation, start_states=starts, solver=best.refit.solver, **ranking_options)
        steps.append(ranking.baseline)
        rankings.append(ranking)
    return Ladder(steps, added, rankings)
