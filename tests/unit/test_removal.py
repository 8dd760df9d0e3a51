"""An earlier effect tried out of a rung's model (torchpaml._diagnostics.ranking.removal): removed where the rule
does not keep it, kept where the model needs it."""

import pytest

from torchpaml import CoulombFriction, CubicStiffness, Oscillator, Rest, SelectionRule, Simulated, fit_physics
from torchpaml._diagnostics.ranking.removal import remove_stand_in, without
from torchpaml._diagnostics.ranking.scoring import score_model


def _records(truth):
    options = dict(amplitude=1.0, duration=60.0, dt=0.05, noise=0.01)
    return (Simulated(truth, "pseudorandom", seeds=[0], **options).experiments(),
            Simulated(truth, "multisine", seeds=[1], **options).experiments())


def _fitted(model, train, validation):
    return score_model(model, fit_physics(model, train, max_nfev=200), validation, SelectionRule())


@pytest.mark.parametrize("friction, removed", [(0.0, True), (0.5, False)], ids=["a stand-in", "needed"])
def test_an_earlier_effect_goes_only_where_the_rule_does_not_keep_it(friction, removed):
    truth = Oscillator(0.2, 2.0, 4.0, learn=()) + CubicStiffness(3.0)
    truth = truth + CoulombFriction(friction) if friction else truth
    train, validation = _records(truth)
    current = _fitted(Oscillator(0.2, 2.0, 4.0, learn=("zeta", "omega0", "gain")) + CoulombFriction(0.1)
                      + CubicStiffness(2.0), train, validation)
    reduced, tried = remove_stand_in(current, ["coulomb_friction"], 2, train, validation, SelectionRule(), Rest(),
                                     200, None)
    (removal,) = tried
    assert removal.removed is removed and removal.rung == 2 and removal.effect == "coulomb_friction"
    assert removal.against == current.nrmse_validation and removal.score is not None
    assert removal.reason.startswith("removed" if removed else "kept")
    if removed:  # the model without it, refitted: the truth's class, at the noise
        assert reduced is removal.score and reduced.model.effect_names() == ("cubic_stiffness",)
        assert reduced.parameters["cubic_stiffness.k3"] == pytest.approx(3.0, rel=0.05)
        assert reduced.nrmse_validation < 1.05 * current.nrmse_validation
    else:  # without the friction the model is worse by the rule
        assert reduced is None and removal.nrmse_validation > 1.5 * current.nrmse_validation


def test_without_keeps_the_other_effects_in_their_order_and_values():
    model = Oscillator() + CoulombFriction(0.3) + CubicStiffness(2.0)
    reduced = without(model, "coulomb_friction")
    assert reduced.effect_names() == ("cubic_stiffness",)
    assert reduced.physical_parameters()["cubic_stiffness.k3"] == pytest.approx(2.0)
    assert model.effect_names() == ("coulomb_friction", "cubic_stiffness")  # the model itself is untouched
