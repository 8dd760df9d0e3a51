"""Discovery acceptance: effects outside the library are found as closed forms; library effects are deferred to.

The cases and their records are those of experiments/discovery/run.py (the README's table): the
oscillator plus a hidden force, 30 s at 20 Hz with 2 % output noise; the forces outside the library
(experiments/discovery/forces.py) act through damping, stiffness and the input.
"""

import pytest
from experiment_modules import load

from torchpaml import CoulombFriction, default_effects, discovery_to_dict, model_ladder, ranking_table

run = load("discovery/run.py")
forces = load("discovery/forces.py")


@pytest.mark.parametrize("case", sorted(forces.OUTSIDE))
def test_an_effect_outside_the_library_is_found_as_its_closed_form(case):
    effect, term, coefficient = forces.OUTSIDE[case]
    found, floor = run.discover(run.truth(effect()))
    content = discovery_to_dict(found)
    terms = dict((t["term"], t["coefficient"]) for t in content["terms"])
    assert term in terms, content
    assert terms[term] == pytest.approx(coefficient, rel=0.1), content  # 2 % noise: the refit lands within a few %
    assert content["recommended"], content["reason"]  # beats the physics and the best library effect by BIC > 10
    errors = content["nrmse_validation"]
    assert errors["physics"] > 1.3 * floor  # the effect was visible to begin with
    assert errors["discovered"] < 1.2 * floor, content
    assert errors["discovered"] < errors["library_best"], content


def test_a_library_effect_is_deferred_to():
    """Coulomb friction is in the library: the closed form finds the smoothed sign, and the named effect wins."""
    found, floor = run.discover(run.truth(CoulombFriction(0.5)), shortlist=1)
    content = discovery_to_dict(found)
    assert "tanh(v/" in content["expression"], content
    assert not content["recommended"], content
    assert content["library_best"] == "coulomb_friction"
    assert content["nrmse_validation"]["library_best"] < 1.2 * floor


def test_on_the_physics_alone_nothing_is_recommended():
    found, _ = run.discover(run.truth(), shortlist=1)
    content = discovery_to_dict(found)
    assert content["expression"] == "0" and content["terms"] == [], content
    assert not content["recommended"]
    assert content["nrmse_validation"]["discovered"] == content["nrmse_validation"]["physics"]


def test_a_shape_the_data_asks_for_is_freed_and_the_ladder_stops_there():
    """Coulomb friction with tanh(v/0.05), not the library's 0.01: eps is freed, and no spurious rung follows."""
    train, validation, floor = run.records(run.truth(CoulombFriction(0.5, eps=0.05)))
    ladder = model_ladder(run.physics(), default_effects(), train, validation, shortlist=2)
    assert ladder.added == ["coulomb_friction"], ranking_table(ladder.rankings[-1])
    assert ladder.final.parameters["coulomb_friction.eps"] == pytest.approx(0.05, rel=0.25)
    assert ladder.final.parameters["coulomb_friction.Fc"] == pytest.approx(0.5, rel=0.1)
    assert ladder.final.nrmse_validation < 1.2 * floor
