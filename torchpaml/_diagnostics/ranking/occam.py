r"""The simpler effect wins: which of a rung's accepted candidates the ladder adds.

Candidates come in three kinds, simplest first: **static** (a force or a map with no state of its own), **with its
own states** (hysteresis, LuGre friction, a lag) and **generic** (:attr:`~torchpaml.AbstractEffect.generic`: a latent
state, an extra mode, a quadratic sensor or input map, a saturation; flexible enough to stand in for almost any
small mismatch, so they are places more than physics). Among the candidates the selection rule accepts over the
rung's baseline, the best (lowest criterion) of the simplest kind is the choice; the best of each more complex kind
then replaces it only where the rule itself accepts it over the choice (criterion lower by more than the
threshold, validation mismatch lower by at least ``min_share``), its own states beyond the choice's charged as
parameters ($\ln n$ each under BIC). On a tie the simpler one is kept. A generic effect thus enters a ladder only
where no physical effect does its job.

:func:`simpler_first` puts the choice first among a ranking's entries and says why in one sentence
(:attr:`~torchpaml.Ranking.simpler`); :func:`simpler_alternatives` names the candidates of a simpler kind that a
rung must refit for the rule to weigh them.
"""

from __future__ import annotations

from torchpaml._diagnostics.ranking.first_order import MIN_ACTING_SHARE
from torchpaml._diagnostics.results import EffectEvidence, ModelScore
from torchpaml._diagnostics.ranking.selection import SelectionRule

__all__ = ["KINDS", "kind", "simpler_alternatives", "simpler_first"]

#: The kinds, simplest first.
KINDS = ("static", "with its own states", "generic")


def kind(entry: EffectEvidence) -> int:
    """The entry's kind, as its index in :data:`KINDS`."""
    return 2 if entry.generic else 1 if entry.states else 0


def _accepted(entries: list[EffectEvidence], baseline: ModelScore, rule: SelectionRule) -> list[EffectEvidence]:
    return [e for e in entries if e.refit is not None and not e.unphysical and rule.accepts(baseline, e.refit)]


def simpler_first(entries: list[EffectEvidence], baseline: ModelScore,
                  rule: SelectionRule) -> tuple[list[EffectEvidence], str | None]:
    """``entries`` (refitted ones by criterion, best first) with the choice of the module docstring first, and the
    sentence that says how it was weighed against the other kinds (``None`` where fewer than two kinds pass)."""
    accepted = _accepted(entries, baseline, rule)
    kinds = sorted({kind(e) for e in accepted})
    if len(kinds) < 2:
        return entries, None
    best = {k: next(e for e in accepted if kind(e) == k) for k in kinds}
    choice, notes = best[kinds[0]], []
    for k in kinds[1:]:
        rival = best[k]
        why_not = rule.why_not(choice.refit, rival.refit, extra=max(rival.states - choice.states, 0))
        if why_not is None:
            notes.append(f"{rival.effect} ({KINDS[k]}) beats {choice.effect} ({KINDS[kind(choice)]}) by the rule, its "
                         f"own states counted as parameters")
            choice = rival
        else:
            notes.append(f"{choice.effect} ({KINDS[kind(choice)]}) is kept over {rival.effect} ({KINDS[k]}): against "
                         f"it, {why_not}")
    return [choice, *(e for e in entries if e is not choice)], "the simpler effect wins: " + "; ".join(notes)


def simpler_alternatives(entries: list[EffectEvidence], baseline: ModelScore,
                         rule: SelectionRule) -> list[EffectEvidence]:
    """The candidates not yet refitted that the rule must weigh: where the best accepted refit is of a more complex
    kind, the best-scored candidate of each simpler kind of which none was refitted (scored, and acting on enough
    samples for its score to judge it)."""
    accepted = _accepted(entries, baseline, rule)
    if not accepted:
        return []
    top = kind(accepted[0])
    refitted_kinds = {kind(e) for e in entries if e.refit is not None}
    waiting = [e for e in sorted(entries, key=lambda e: -e.score) if e.refit is None and e.failure is None
               and e.acting >= MIN_ACTING_SHARE and kind(e) < top and kind(e) not in refitted_kinds]
    return [next(e for e in waiting if kind(e) == k) for k in sorted({kind(e) for e in waiting})]
