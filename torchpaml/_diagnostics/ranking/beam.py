r"""Beyond the greedy ladder: a small beam of models climbs, and validation chooses among their ends.

A greedy ladder takes each rung's best candidate; an early stand-in can then lead it to a worse end than a path
through the rung's runner-up would. So the ladder keeps up to ``beam`` models (:data:`BEAM`, 3) per rung:

1. **Proposals.** Each model of the beam whose ranking recommends an effect proposes its accepted candidates: the
   recommended one, then each other refitted candidate the selection rule accepts over that rung's baseline (physical,
   not one of the recommended one's equivalents, which give its output, and not of a more complex kind than the
   recommended one: the simpler-effect rule, :mod:`~torchpaml._diagnostics.ranking.occam`, already found that it
   does not beat it), in the ranking's order.
2. **The next beam** (:func:`next_beam`). The greedy path's proposal (the first of the greedy path's model) always
   climbs; the other places go to the remaining proposals within :data:`REACH` (2) of its validation mismatch, by
   their validation criterion, the model's own states charged as parameters (:func:`charged`), lowest first. A
   proposal whose effects are those of a model the beam already holds or held is the same model and is passed over,
   and so is a model that a removal makes one of those (the greedy path's excepted).
3. **The end** (:func:`chosen_end`). A model whose ranking recommends nothing ends. Among the ends, the greedy path's
   is kept unless another end beats it by the selection rule itself (its charged criterion lower by more than the
   threshold, its validation mismatch lower by at least ``min_share``), and then the best such end by its charged
   criterion is chosen. All on the validation records; every end is reported (:class:`BeamEnd`,
   ``Ladder.beam``, ``diagnosis.json``'s ``beam``), and so is each path the beam left behind (:func:`left_behind`).

With ``beam=1`` the ladder is greedy. The removal moves (:mod:`~torchpaml._diagnostics.ranking.removal`) run on
every model of the beam: removing an earlier effect after a later one is added is the swap of the earlier effect for
the later.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from torchpaml._diagnostics.results import EffectEvidence, ModelScore, Ranking
from torchpaml._diagnostics.ranking.occam import kind
from torchpaml._diagnostics.ranking.selection import SelectionRule

__all__ = ["BEAM", "REACH", "BeamEnd", "charged", "chosen_end", "left_behind", "next_beam", "proposals"]

#: How many models the ladder keeps per rung by default.
BEAM = 3
#: A runner-up climbs only where its validation mismatch is within this factor of the greedy proposal's: one more
#: effect can close a factor of two (the cascaded tanks' better path starts 1.5 times behind), not an order of
#: magnitude, and a path that far behind costs a whole ladder of fits.
REACH = 2.0


@dataclass(frozen=True)
class BeamEnd:
    """Where one model of the beam ended.

    Attributes:
        effects: its effects, in the order its path added them.
        nrmse_validation: its validation mismatch.
        criterion: its validation criterion, its own states charged as parameters (:func:`charged`).
        greedy: it is the end of the greedy path (each rung's best candidate).
        chosen: it is the ladder's answer.
        reason: why it was or was not chosen, in one sentence.
        ended: its ranking recommended nothing (else the beam left it behind: its proposals lost the beam's places,
            or a removal made it a model the beam had already climbed from; not a candidate answer).
        score: its last model, fitted and scored.
    """

    effects: tuple[str, ...]
    nrmse_validation: float
    criterion: float
    greedy: bool
    chosen: bool
    reason: str
    ended: bool = True
    score: ModelScore | None = field(default=None, repr=False)


def left_behind(effects: tuple[str, ...], score: ModelScore, rule: SelectionRule, reason: str) -> BeamEnd:
    """A path the beam left behind (``reason``) before its ranking recommended nothing: reported, not chosen from."""
    return BeamEnd(tuple(effects), score.nrmse_validation, charged(score, rule), False, False,
                   f"left behind: {reason}", ended=False, score=score)


def own_states(score: ModelScore) -> int:
    """The states ``score``'s model has beyond its physics': its effects' own."""
    return score.model.state_dim - score.model.without_effects().state_dim


def charged(score: ModelScore, rule: SelectionRule) -> float:
    """``score``'s validation criterion with its effects' own states charged as parameters ($\\ln n$ each under BIC):
    the measure on which models of different paths, not nested in each other, are compared."""
    return score.criterion + (rule.penalty(score.samples, own_states(score)) if score.samples else 0.0)


def proposals(ranking: Ranking, width: int) -> list[EffectEvidence]:
    """At most ``width`` of ``ranking``'s accepted candidates, the recommended one first (module docstring, 1);
    none where it recommends nothing."""
    first = ranking.recommended
    if first is None:
        return []
    others = [e for e in ranking.entries if e is not first and e.refit is not None and not e.unphysical
              and e.effect not in ranking.equivalent and kind(e) <= kind(first)
              and ranking.rule.accepts(ranking.baseline, e.refit)]
    return [first, *others][:width]


def next_beam(greedy: tuple[int, EffectEvidence, frozenset[str]] | None,
              others: list[tuple[int, EffectEvidence, frozenset[str]]], seen: set[frozenset[str]], width: int,
              rule: SelectionRule) -> list[tuple[int, EffectEvidence]]:
    """The proposals that climb (module docstring, 2), each ``(model's place in the beam, proposal)``, the greedy
    path's first. ``greedy``: the greedy path's proposal, ``(place, proposal, the effects it would make)`` (``None``
    where that path ended), which always climbs; ``others``: the other proposals, each within :data:`REACH` of the
    greedy one's validation mismatch (of the lowest where the greedy path ended); ``seen``: the effect sets the beam
    holds or held (updated)."""
    chosen = []
    if greedy is not None:
        seen.add(greedy[2])
        chosen.append(greedy[:2])
    best = greedy[1] if greedy is not None else min((o[1] for o in others), key=lambda e: e.refit.nrmse_validation,
                                                   default=None)
    for place, entry, effects in sorted(others, key=lambda offer: charged(offer[1].refit, rule)):
        near = entry.refit.nrmse_validation <= REACH * best.refit.nrmse_validation
        if len(chosen) < width and near and effects not in seen:
            seen.add(effects)
            chosen.append((place, entry))
    return chosen


def chosen_end(ends: list[tuple[tuple[str, ...], ModelScore, bool]], rule: SelectionRule) -> tuple[int, list[BeamEnd]]:
    """Which of the beam's ``ends`` (``(effects, score, greedy)``) is the ladder's answer (module docstring, 3): its
    index, and every end as a :class:`BeamEnd` that says why."""
    greedy = next(i for i, (_, _, is_greedy) in enumerate(ends) if is_greedy)
    base = ends[greedy][1]
    beating = [i for i, (_, score, _) in enumerate(ends)
               if i != greedy and rule.accepts(base, score, own_states(score) - own_states(base), nested=False)]
    choice = min(beating, key=lambda i: charged(ends[i][1], rule)) if beating else greedy
    described = []
    for i, (effects, score, is_greedy) in enumerate(ends):
        named = " + ".join(effects) or "the physics alone"
        if i == choice:
            reason = ("chosen: the greedy path's end, which no other end beats by the rule" if i == greedy else
                      f"chosen: it beats the greedy path's end by the rule, on validation, and ends lowest of those "
                      "that do")
        elif i == greedy:
            reason = "not chosen: the greedy path's end, beaten by the rule on validation"
        else:
            reason = (f"not chosen: {named} does not beat the greedy path's end by the rule on validation"
                      if i not in beating else "not chosen: it beats the greedy path's end, but another end is lower")
        described.append(BeamEnd(tuple(effects), score.nrmse_validation, charged(score, rule), is_greedy,
                                 i == choice, reason, score=score))
    return choice, described
