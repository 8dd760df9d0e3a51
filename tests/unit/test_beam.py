"""The ladder's beam (``torchpaml._diagnostics.ranking.beam``): which proposals climb and which end is the answer, on
hand-made evidence whose criteria sit on both sides of each edge."""

import math

import pytest

from torchpaml import Ranker, CoulombFriction, Hysteresis, Oscillator, SelectionRule
from torchpaml._diagnostics.ranking.beam import charged, chosen_end, next_beam, proposals
from torchpaml._diagnostics.results import EffectEvidence, ModelScore, Ranking
from torchpaml._errors import ConfigurationError

SAMPLES = 1000  # ln n = 6.91: one own state costs 6.91 of BIC
RULE = SelectionRule()  # BIC, threshold 10, min_share 5 %


def score(criterion: float, validation: float, model=None) -> ModelScore:
    return ModelScore("m", "m", {}, 0.01, validation, criterion, model or Oscillator(), samples=SAMPLES)


def evidence(effect: str, criterion: float | None, validation: float = 0.05, unphysical=(), states: int = 0,
             generic: bool = False) -> EffectEvidence:
    refit = None if criterion is None else score(criterion, validation)
    return EffectEvidence(effect, effect, 1.0, 1, 0.0, refit=refit, unphysical=list(unphysical), states=states,
                          generic=generic)


def test_a_model_proposes_its_accepted_candidates_recommended_first_and_no_equivalent_or_unphysical_one():
    baseline = score(0.0, 0.10)
    entries = [evidence("a", -50.0), evidence("twin", -49.99), evidence("b", -40.0), evidence("bad", -45.0,
               unphysical=["negative"]), evidence("weak", -5.0), evidence("unfitted", None)]
    ranking = Ranking(baseline, entries, RULE, equivalent=["twin"])
    assert [e.effect for e in proposals(ranking, 3)] == ["a", "b"]
    assert [e.effect for e in proposals(ranking, 1)] == ["a"]
    assert proposals(Ranking(baseline, [evidence("weak", -5.0), evidence("b", -40.0)], RULE), 3) == []


def test_a_runner_up_of_a_more_complex_kind_than_the_recommended_one_is_not_proposed():
    """The simpler-effect rule kept the static choice over them: a generic or memory runner-up would climb a path the
    rule already turned down (Silverbox's latent state beside its constant force, 200 of 255 s)."""
    baseline = score(0.0, 0.10)
    static = [evidence("force", -50.0), evidence("latent", -49.0, generic=True), evidence("lag", -48.0, states=1),
              evidence("spring", -40.0)]
    assert [e.effect for e in proposals(Ranking(baseline, static, RULE), 3)] == ["force", "spring"]
    memory = [evidence("lag", -50.0, states=1), evidence("latent", -49.0, generic=True), evidence("force", -40.0)]
    assert [e.effect for e in proposals(Ranking(baseline, memory, RULE), 3)] == ["lag", "force"]


def test_the_greedy_proposal_always_climbs_and_the_others_take_the_places_by_their_criterion():
    greedy = (0, evidence("a", -50.0), frozenset({"a"}))
    others = [(0, evidence("b", -60.0), frozenset({"b"})), (1, evidence("c", -70.0), frozenset({"c"})),
              (1, evidence("d", -80.0), frozenset({"d"}))]
    seen = {frozenset({"d"})}  # a model the beam held: passed over
    climbing = next_beam(greedy, others, seen, 3, RULE)
    assert [entry.effect for _, entry in climbing] == ["a", "c", "b"]
    assert [place for place, _ in climbing] == [0, 1, 0]
    assert seen >= {frozenset({"a"}), frozenset({"b"}), frozenset({"c"})}
    assert [entry.effect for _, entry in next_beam(None, others, set(), 1, RULE)] == ["d"]


@pytest.mark.parametrize("behind, climbs", [(1.9, True), (2.1, False)])
def test_a_runner_up_climbs_only_within_reach_of_the_greedy_proposals_validation_mismatch(behind, climbs):
    greedy = (0, evidence("a", -50.0, 0.05), frozenset({"a"}))
    far = (0, evidence("b", -60.0, behind * 0.05), frozenset({"b"}))
    climbing = next_beam(greedy, [far], set(), 3, RULE)
    assert [entry.effect for _, entry in climbing] == (["a", "b"] if climbs else ["a"])


def test_an_effects_own_states_are_charged_when_paths_are_compared():
    static, memory = score(-100.0, 0.05, Oscillator() + CoulombFriction(0.1)), score(-100.0, 0.05,
                                                                                     Oscillator() + Hysteresis())
    assert charged(static, RULE) == -100.0
    assert charged(memory, RULE) == pytest.approx(-100.0 + math.log(SAMPLES))


@pytest.mark.parametrize("gain, share, chosen", [(10.5, 0.2, 1), (9.5, 0.2, 0), (10.5, 0.04, 0)],
                         ids=["beats by the rule", "criterion within the threshold", "validation within min_share"])
def test_another_end_replaces_the_greedy_one_only_where_it_beats_it_by_the_rule(gain, share, chosen):
    greedy = score(-100.0, 0.05)
    rival = score(-100.0 - gain, 0.05 * (1 - share))
    choice, ends = chosen_end([(("a",), greedy, True), (("b", "c"), rival, False)], RULE)
    assert choice == chosen and [end.chosen for end in ends] == [chosen == 0, chosen == 1]
    assert ends[0].greedy and not ends[1].greedy and ends[1].effects == ("b", "c")
    assert ends[choice].reason.startswith("chosen") and ends[1 - choice].reason.startswith("not chosen")


def test_among_the_ends_that_beat_the_greedy_one_the_lowest_is_chosen():
    ends = [(("a",), score(-100.0, 0.05), True), (("b",), score(-130.0, 0.04), False),
            (("c",), score(-150.0, 0.04), False)]
    choice, described = chosen_end(ends, RULE)
    assert choice == 2 and "another end is lower" in described[1].reason


@pytest.mark.parametrize("beam", [0, 1.5, True])
def test_a_beam_that_is_not_a_whole_number_of_at_least_one_is_refused(beam):
    with pytest.raises(ConfigurationError, match="beam must be at least 1"):
        Ranker(beam=beam)


def test_the_verdict_names_the_greedy_end_only_where_another_path_is_chosen():
    from types import SimpleNamespace

    from torchpaml._diagnostics.diagnosis import Diagnosis

    _, ends = chosen_end([(("a",), score(-100.0, 0.05), True), (("b", "c"), score(-150.0, 0.03), False)], RULE)
    clause = Diagnosis._beam.fget(SimpleNamespace(ladder=SimpleNamespace(beam=ends)))
    assert clause == (" (the greedy path ends at a, 5.00 % on validation; this path, through a runner-up, beats it by "
                      "the rule)")
    _, kept = chosen_end([(("a",), score(-100.0, 0.05), True), (("b",), score(-105.0, 0.049), False)], RULE)
    assert Diagnosis._beam.fget(SimpleNamespace(ladder=SimpleNamespace(beam=kept))) == ""
