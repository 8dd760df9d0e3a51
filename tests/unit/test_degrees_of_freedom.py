"""Forces on a chosen degree of freedom: ``effect.on("v2")``, the placements the ranking tries, and copies of one
effect that keep their own values inside the simulators' parametrization cache."""

import copy

import pytest
import torch
from torch.nn.utils import parametrize

from two_mass import TRUTH, TwoMass
from torchpaml import (ConfigurationError, CoulombFriction, CubicStiffness, Hysteresis, Oscillator, OutputSaturation,
                       simulate, time_grid, pseudorandom)


def _state(*values):
    return torch.tensor([values], dtype=torch.float64)


def test_a_force_on_v2_enters_the_equation_of_v2_only():
    physics = TwoMass(**TRUTH)
    model = physics + CoulombFriction(0.4, 0.01).on("v2")
    x, u = _state(0.1, -0.2, 0.3, 0.05), _state(0.7)
    extra = model.derivative(0.0, x, u) - physics.derivative(0.0, x, u)
    expected = -0.4 * torch.tanh(torch.tensor(0.05 / 0.01, dtype=torch.float64))
    assert torch.allclose(extra, torch.stack([torch.zeros(()), torch.zeros(()), torch.zeros(()), expected])[None],
                          atol=1e-15)


def test_a_force_on_a_degree_of_freedom_reads_its_position():
    model = TwoMass(**TRUTH) + CubicStiffness(2.0).on("v1")  # k3 x^3 on mass 1, from x1
    x, u = _state(0.5, -0.3, 0.0, 0.0), _state(0.0)
    extra = (model.derivative(0.0, x, u) - TwoMass(**TRUTH).derivative(0.0, x, u)).detach()
    assert float(extra[0, 2]) == pytest.approx(-2.0 * 0.5**3, rel=1e-14) and float(extra[0, 3]) == 0.0


def test_an_effect_with_memory_sees_its_degree_of_freedom_as_position_and_velocity():
    model = TwoMass(**TRUTH) + Hysteresis(1.0, gamma=0.5, delta=0.2).on("v2")
    x = torch.tensor([[0.1, -0.2, 0.3, 0.05, 0.02]], dtype=torch.float64)  # z of the loop last
    rate = model.derivative(0.0, x, _state(0.0))[0, -1]
    v, z = 0.05, 0.02  # z' = v - gamma |v| z - delta v |z| with v = v2
    assert float(rate) == pytest.approx(v - 0.5 * abs(v) * z - 0.2 * v * abs(z), rel=1e-14)


def test_the_names_and_the_placements():
    placed = CoulombFriction().on("v2")
    assert placed.name == "coulomb_friction_v2" and placed.acts_on == "v2" and placed.equation.endswith("on v2")
    assert CoulombFriction().name == "coulomb_friction"  # the original is unchanged
    assert [e.name for e in CoulombFriction().placements(TwoMass())] == ["coulomb_friction_v1", "coulomb_friction_v2"]
    assert [e.name for e in CoulombFriction().placements(Oscillator())] == ["coulomb_friction"]
    assert [e.name for e in OutputSaturation().placements(TwoMass())] == ["output_saturation"]  # not a force


@pytest.mark.parametrize("effect, message", [
    (CoulombFriction(), r"2 degrees of freedom: name the one it acts on, coulomb_friction.on\('v1'\) or "),
    (CoulombFriction().on("v3"), r"acts on 'v3', which is no velocity .* \['v1', 'v2'\]"),
])
def test_an_unplaced_or_misplaced_force_is_refused_with_the_fix(effect, message):
    with pytest.raises(ConfigurationError, match=message):
        TwoMass() + effect


def test_only_a_force_can_be_placed():
    with pytest.raises(ConfigurationError, match="output_saturation is not a force"):
        OutputSaturation().on("v2")


def test_copies_of_one_effect_read_their_own_values_in_the_parametrization_cache():
    original = CoulombFriction(0.3, 0.05)
    first, second = copy.deepcopy(original), copy.deepcopy(original)
    with torch.no_grad():
        first.parametrizations.eps.original.fill_(-1.0)
        second.parametrizations.eps.original.fill_(1.0)
    with parametrize.cached():  # the simulators' context: a shared class once served the first value read to all
        assert [float(e.eps) for e in (original, first, second)] == pytest.approx([0.05, torch.e**-1, torch.e])


def test_two_placements_of_one_force_simulate_as_one_at_zero_strength():
    t = time_grid(10.0, 0.02)
    u = pseudorandom(t, 1.0, 0.5, seed=0)
    friction = CoulombFriction(0.0, 0.01)  # both placements are copies of it, as the ranking makes them
    one = (TwoMass(**TRUTH) + friction.on("v2")).assign(**{"coulomb_friction_v2.Fc": 0.4})
    both = copy.deepcopy(one) + friction.on("v1")
    with torch.no_grad():
        assert torch.equal(simulate(both, t, u), simulate(one, t, u))
