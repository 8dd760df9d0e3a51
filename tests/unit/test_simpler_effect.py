"""The simpler-effect rule (``torchpaml._diagnostics.ranking.occam``): which accepted candidate a rung adds, on
hand-made evidence whose criteria sit on both sides of each edge, and which simpler candidates it refits."""

import math

import pytest

from torchpaml import Oscillator, SelectionRule
from torchpaml._diagnostics.ranking.occam import simpler_alternatives, simpler_first
from torchpaml._diagnostics.results import EffectEvidence, ModelScore

SAMPLES = 1000  # ln n = 6.91: one own state costs 6.91 of BIC


def score(criterion: float, validation: float, train: float = 0.01) -> ModelScore:
    return ModelScore("m", "m", {}, train, validation, criterion, Oscillator(), samples=SAMPLES)


def evidence(effect: str, criterion: float | None, validation: float = 0.05, *, states: int = 0, generic=False,
             first_order: float = 1.0) -> EffectEvidence:
    refit = None if criterion is None else score(criterion, validation)
    return EffectEvidence(effect, effect, first_order, 1, 0.0, refit=refit, states=states, generic=generic)


BASELINE = score(0.0, 0.10, train=0.02)
RULE = SelectionRule()  # BIC, threshold 10, min_share 5 %


@pytest.mark.parametrize("lead, kept", [(10.0 + math.log(SAMPLES) + 0.5, "hysteresis"),
                                        (10.0 + math.log(SAMPLES) - 0.5, "quadratic_damping")])
def test_an_effect_with_its_own_state_must_beat_the_static_one_by_the_rule_its_state_charged(lead, kept):
    static = evidence("quadratic_damping", -100.0, 0.05)
    memory = evidence("hysteresis", -100.0 - lead, 0.04, states=1)
    ordered, sentence = simpler_first([memory, static], BASELINE, RULE)
    assert ordered[0].effect == kept and {e.effect for e in ordered} == {"hysteresis", "quadratic_damping"}
    assert sentence.startswith("the simpler effect wins: ")
    assert ("1 own state(s) counted as parameters" in sentence) == (kept == "quadratic_damping")


def test_a_tie_keeps_the_static_effect_even_where_the_memory_effects_criterion_is_lower():
    static, memory = evidence("coulomb_friction", -50.0, 0.05), evidence("dynamic_friction", -52.0, 0.049, states=1)
    ordered, sentence = simpler_first([memory, static], BASELINE, RULE)
    assert ordered[0] is static and "coulomb_friction (static) is kept over dynamic_friction" in sentence


def test_a_generic_effect_is_weighed_against_the_best_physical_kind_left():
    static = evidence("cubic_stiffness", -40.0, 0.08)
    memory = evidence("hysteresis", -80.0, 0.05, states=1)  # beats the static one by 40 - 6.9 > 10, 37 %
    generic = evidence("latent_state", -85.0, 0.049, states=1, generic=True)  # a tie with hysteresis
    ordered, sentence = simpler_first([generic, memory, static], BASELINE, RULE)
    assert [e.effect for e in ordered][:1] == ["hysteresis"]
    assert "hysteresis (with its own states) beats cubic_stiffness (static)" in sentence
    assert "hysteresis (with its own states) is kept over latent_state (generic)" in sentence


def test_one_kind_alone_or_nothing_accepted_leaves_the_order_as_it_is():
    entries = [evidence("cubic_stiffness", -40.0), evidence("quadratic_damping", -30.0)]
    assert simpler_first(entries, BASELINE, RULE) == (entries, None)
    rejected = [evidence("hysteresis", -5.0, states=1), evidence("cubic_stiffness", -4.0)]  # within the threshold
    assert simpler_first(rejected, BASELINE, RULE) == (rejected, None)


def test_a_memory_effect_that_leads_asks_for_the_best_scored_static_candidate_to_be_refitted():
    memory = evidence("dynamic_friction", -60.0, states=1)
    waiting = [evidence("coulomb_friction", None, first_order=0.3), evidence("quadratic_damping", None, first_order=0.5),
               evidence("input_lag", None, states=1, first_order=0.9)]
    assert [e.effect for e in simpler_alternatives([memory, *waiting], BASELINE, RULE)] == ["quadratic_damping"]
    static = evidence("cubic_stiffness", -20.0)  # a static one refitted already: the rule has its kind
    assert simpler_alternatives([memory, static, *waiting], BASELINE, RULE) == []
    assert simpler_alternatives([evidence("cubic_stiffness", -60.0), *waiting], BASELINE, RULE) == []
