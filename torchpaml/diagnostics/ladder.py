r"""The model ladder: physics -> physics + best effect -> ... until no candidate helps significantly.

Each rung runs :func:`~torchpaml.diagnostics.rank_missing_effects` on the current model with the
candidates not yet added (and that apply). If it recommends an effect (its criterion beats the current
model's by more than the threshold, its validation mismatch falls by at least ``min_share``, and its
parameters are physical), the refitted model, fitted once more to the last digits, becomes the next
rung; otherwise the ladder stops.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from matplotlib.figure import Figure

from torchpaml.data import Experiment
from torchpaml.diagnostics.ranking import ModelScore, Ranking, rank_missing_effects
from torchpaml.physics.effects import AbstractEffect

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

    def to_dicts(self) -> list[dict]:
        """One dict per rung: ``{model, equation, added, nrmse_train, nrmse_validation, criterion, parameters,
        uncertainty, identifiability, substeps}`` (``uncertainty``: standard errors; ``identifiability``: the
        warning or ``None``; ``substeps``: the RK4 steps per sample the rung was fitted and scored at)."""
        return [
            {"model": s.name, "equation": s.equation, "added": None if i == 0 else self.added[i - 1],
             "nrmse_train": s.nrmse_train, "nrmse_validation": s.nrmse_validation, "criterion": s.criterion,
             "parameters": s.parameters, "uncertainty": s.uncertainty, "identifiability": s.warning,
             "substeps": s.model.substeps}
            for i, s in enumerate(self.steps)
        ]

    def figure(self, discovered: ModelScore | None = None) -> Figure:
        """Validation (and training) mismatch per rung, on a log scale; ``discovered``: the physics with the
        discovered force (:func:`~torchpaml.diagnostics.discover_missing_force`), drawn as a rung of its own."""
        fig = Figure(figsize=(7, 4), layout="constrained")
        ax = fig.subplots()
        labels = ["physics", *(f"+ {name}" for name in self.added)]
        steps = range(len(self.steps))
        ax.semilogy(steps, [100 * s.nrmse_validation for s in self.steps], "o-", label="validation")
        ax.semilogy(steps, [100 * s.nrmse_train for s in self.steps], "s--", label="training")
        if discovered is not None:
            last = len(self.steps)
            ax.semilogy([last], [100 * discovered.nrmse_validation], "D", color="tab:red", label="physics + discovered")
            ax.semilogy([last], [100 * discovered.nrmse_train], "x", color="tab:red")
            labels.append("physics\n+ discovered")
            steps = range(last + 1)
        ax.set_xticks(list(steps), labels)
        ax.set_ylabel("mismatch (%)")
        ax.set_title("model ladder")
        ax.legend()
        return fig


def model_ladder(
    physics,
    candidates: Sequence[AbstractEffect],
    train: Experiment | Sequence[Experiment],
    validation: Experiment | Sequence[Experiment],
    *,
    max_steps: int | None = None,
    **ranking_options,
) -> Ladder:
    """Climb the ladder (module docstring); ``ranking_options`` go to :func:`rank_missing_effects`.

    ``max_steps`` bounds the number of effects added (default: as many as keep helping).
    """
    ranking = rank_missing_effects(physics, candidates, train, validation, **ranking_options)
    steps, added, rankings = [ranking.baseline], [], [ranking]
    while ranking.recommended is not None and (max_steps is None or len(added) < max_steps):
        best = ranking.recommended
        added.append(best.effect)
        remaining = [e.effect for e in ranking.entries if e.effect != best.effect]
        # the next rung's baseline is the refit's model fitted to the last digits (the refit stopped early)
        starts = best.refit.train_states if ranking_options.get("initial_state") == "estimate" else None
        ranking = rank_missing_effects(best.refit.model, [c for c in candidates if c.name in remaining], train,
                                       validation, start_states=starts, **ranking_options)
        steps.append(ranking.baseline)
        rankings.append(ranking)
    return Ladder(steps, added, rankings)
