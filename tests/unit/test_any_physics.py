"""Effects on any physics: rates on named state equations, input and output maps; forces only where they apply."""

import pytest
import torch

from experiment_modules import load
from torchpaml import CubicStiffness, default_effects, OutputSaturation, pseudorandom, simulate, time_grid

tanks = load("cascaded_tanks/tanks.py")


def test_a_rate_on_a_named_state_changes_that_equation_and_the_flow_it_feeds():
    base = tanks.TwoTanks(0.02, 0.02, 0.01, 0.05)
    model = base + tanks.TorricelliOutflow(1.0, tank="upper")  # g = 1: the square-root law
    x, u = torch.tensor([[4.0, 2.0]]), torch.tensor([[1.0]])
    with torch.no_grad():
        extra = model.derivative(0.0, x, u) - base.derivative(0.0, x, u)
    assert float(extra[0, 0]) == pytest.approx(-0.02 * (2.0 - 4.0))  # -k1 (sqrt(4) - 4): k1 x -> k1 sqrt(x)
    assert float(extra[0, 1]) == pytest.approx(+0.02 * (2.0 - 4.0))  # the same flow into the lower tank, at k2


def test_maps_apply_to_any_physics_and_forces_are_refused_with_the_reason():
    base = tanks.TwoTanks()
    t = time_grid(200.0, 4.0)
    u = 3.0 + pseudorandom(t, 1.0, seed=0)
    y = simulate(base + OutputSaturation(0.1), t, u)
    assert bool(torch.all(y.abs() < 10.0))  # ymax = 1/s = 10
    with pytest.raises(TypeError, match="cubic_stiffness is a force.*TwoTanks declares none"):
        base + CubicStiffness()
    with pytest.raises(TypeError, match=r"acts on the state\(s\) \['upper', 'lower'\]"):
        from torchpaml import Oscillator

        Oscillator() + tanks.TorricelliOutflow(tank="lower")


def test_the_default_candidates_that_apply_to_first_order_physics():
    applicable = {e.name for e in default_effects() if e.applies_to(tanks.TwoTanks()) is None}
    assert applicable == {"input_saturation", "output_saturation", "dead_zone", "input_lag", "sensor_lag",
                          "magnitude_sensor", "quadratic_sensor", "quadratic_input", "extra_mode", "latent_state", "feedthrough"}


def test_first_order_physics_with_the_default_candidates_runs_and_lists_the_skipped_ones():
    from torchpaml import Record
    from torchpaml._diagnostics import rank_missing_effects

    truth = tanks.TwoTanks(0.02, 0.01, 0.01, 0.05) + OutputSaturation(0.1)
    t = time_grid(800.0, 4.0)
    records = []
    for seed in (0, 1):
        u = 3.0 + pseudorandom(t, 1.5, period=40.0, seed=seed)
        with torch.no_grad():
            records.append(Record(t, u[0], truth(t, u)[0]))
    physics = tanks.TwoTanks(0.02, 0.01, 0.01, 0.05, learn=("k1", "k3", "k4"))
    ranking = rank_missing_effects(physics, default_effects(), records[0], records[1], shortlist=1)
    assert set(ranking.skipped) == {"cubic_stiffness", "quadratic_stiffness", "pendulum_restoring",
                                    "coulomb_friction", "quadratic_damping", "constant_force", "hysteresis",
                                    "dynamic_friction"}
    assert all("is a force" in reason for reason in ranking.skipped.values())
    assert ranking.recommended is not None and ranking.recommended.effect == "output_saturation"


def test_a_second_order_model_with_effects_still_takes_a_neural_force():
    from torchpaml import ForceAugmented, MLPForce, Oscillator

    t = time_grid(5.0, 0.05)
    u = pseudorandom(t, 1.0, seed=0)
    model = Oscillator() + CubicStiffness(1.0)
    force = MLPForce()
    torch.nn.init.zeros_(force.net[-1].weight)
    torch.nn.init.zeros_(force.net[-1].bias)
    with torch.no_grad():
        assert torch.allclose(ForceAugmented(model, force)(t, u), model(t, u), atol=1e-12)
    with pytest.raises(TypeError, match="second-order"):
        ForceAugmented(tanks.TwoTanks(), MLPForce())
