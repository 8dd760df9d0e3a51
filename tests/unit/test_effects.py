"""The effect library and ``physics + effect`` composition, against hand-written models."""

import pytest
import torch

from torchpaml import RK4, Auto
from torchpaml import (
    AbstractEffect,
    ComposedModel,
    CoulombFriction,
    CubicStiffness,
    DeadZone,
    DynamicFriction,
    EFFECTS,
    EffectState,
    Hysteresis,
    InputLag,
    InputSaturation,
    Oscillator,
    OutputSaturation,
    Pendulum,
    PendulumRestoring,
    QuadraticDamping,
    Record,
    default_effects,
    simulate,
)
from torchpaml.engine import complete_state
from torchpaml._physics.effects import _tanh_ratio
from torchpaml._signals import pseudorandom, pseudorandom_knots, sine

TOL = dict(solver=Auto(rtol=1e-7))
TIGHT = dict(solver=Auto(rtol=1e-9))


def test_the_library_has_every_effect_the_issue_names():
    assert set(EFFECTS) == {
        "cubic_stiffness", "quadratic_stiffness", "pendulum_restoring", "coulomb_friction", "quadratic_damping",
        "input_saturation", "output_saturation", "constant_force", "dead_zone", "hysteresis", "dynamic_friction",
        "input_lag", "sensor_lag", "magnitude_sensor", "quadratic_sensor", "quadratic_input",
        "extra_mode", "latent_state", "feedthrough",
    }


@pytest.mark.parametrize("effect", default_effects(), ids=lambda e: e.name)
def test_every_effect_at_zero_strength_leaves_the_physics_unchanged(effect, grid):
    u = pseudorandom(grid, 1.0, seed=1)
    base = Oscillator(zeta=0.3, omega0=2.0)
    with torch.no_grad():
        exact = simulate(base, grid, u)
        composed = simulate(base + effect, grid, u, knots=pseudorandom_knots(grid), **TOL)
    assert torch.allclose(composed, exact, rtol=0, atol=1e-6)  # dopri5 at rtol 1e-7 against the exact path


def test_pendulum_restoring_at_full_strength_is_the_pendulum(grid):
    u = sine(grid, 2.0, 1.0)
    with torch.no_grad():
        composed = simulate(Oscillator(zeta=0.5, omega0=2.0) + PendulumRestoring(lam=1.0), grid, u, **TIGHT)
        pendulum = simulate(Pendulum(zeta=0.5, omega0=2.0), grid, u, **TIGHT)
    # Pendulum's output is sin x. Two adaptive solves of one ODE, through an input with a kink at
    # every sample, take different steps; at rtol 1e-9 they agree to about 2e-7.
    assert torch.allclose(torch.sin(composed), pendulum, rtol=0, atol=1e-6)


def test_composed_acceleration_is_the_sum_of_the_terms():
    model = Oscillator(zeta=0.2, omega0=1.5, gain=2.0) + CubicStiffness(k3=0.7) + QuadraticDamping(c2=0.3)
    x, v, u = torch.randn(3, 5, dtype=torch.float64)
    expected = 2.0 * u - 2 * 0.2 * 1.5 * v - 1.5**2 * x - 0.7 * x**3 - 0.3 * v * v.abs()
    assert torch.allclose(model.acceleration(None, x, v, u), expected, rtol=1e-14, atol=0)


def test_saturations_and_dead_zone_match_their_formulas():
    u = torch.linspace(-3, 3, 61, dtype=torch.float64)
    assert torch.allclose(InputSaturation(s=0.5).input_map(u), 2.0 * torch.tanh(u / 2.0), rtol=1e-14, atol=0)
    assert torch.allclose(OutputSaturation(s=0.25).output_map(u), 4.0 * torch.tanh(u / 4.0), rtol=1e-14, atol=0)
    expected = torch.where(u.abs() > 1.0, u - torch.sign(u), torch.zeros_like(u))
    assert torch.allclose(DeadZone(d=1.0).input_map(u), expected, rtol=0, atol=1e-15)


def test_the_saturation_quotient_is_smooth_through_zero_strength():
    z = torch.linspace(-2, 2, 9, dtype=torch.float64)
    for s in (0.0, 1e-9, 1e-6, 1e-3):
        value = _tanh_ratio(torch.tensor(s, dtype=torch.float64), z)
        exact = z if s == 0 else torch.tanh(s * z) / s
        assert torch.allclose(value, exact, rtol=1e-12, atol=0)
    s = torch.tensor(0.0, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda s: _tanh_ratio(s, z), (s,))  # d/ds at s = 0 exists (it is 0)


def test_composition_flattens_names_parameters_and_rejects_clashes():
    model = Oscillator(zeta=0.3) + CubicStiffness() + QuadraticDamping()
    assert isinstance(model, ComposedModel) and list(model.effects) == ["cubic_stiffness", "quadratic_damping"]
    assert model.display_name == "Oscillator + cubic_stiffness + quadratic_damping"
    assert set(model.physical_parameters()) == {"zeta", "omega0", "gain", "cubic_stiffness.k3", "quadratic_damping.c2"}
    assert model.learnable_names() == ["zeta", "cubic_stiffness.k3", "quadratic_damping.c2"]
    model.assign(**{"cubic_stiffness.k3": 1.5, "zeta": 0.4}).set_learnable("omega0")
    assert model.physical_parameters()["cubic_stiffness.k3"] == 1.5 and "omega0" in model.learnable_names()
    assert "- k3*x^3" in model.describe()
    with pytest.raises(ValueError, match=r"effect\(s\) \['cubic_stiffness'\] added twice"):
        model + CubicStiffness()
    with pytest.raises(TypeError, match="unsupported operand"):
        Oscillator() + 3.0
    with pytest.raises(TypeError, match=r"an effect is added to physics \(physics \+ effect\)"):
        CubicStiffness() + QuadraticDamping()


def test_forces_need_a_degree_of_freedom():
    from torchpaml._physics import AbstractPhysics

    class Tank(AbstractPhysics):
        state_names = ("level",)

    with pytest.raises(TypeError, match="Tank declares none .*degrees_of_freedom"):
        Tank() + CubicStiffness()


def test_gradients_reach_effect_parameters_through_the_ode(grid):
    t = grid[:500]
    u, knots = pseudorandom(t, 1.0, seed=3), pseudorandom_knots(t)
    model = Oscillator(zeta=0.3, learn=()) + CubicStiffness(k3=0.5)
    y = simulate(model, t, u, knots=knots, **TOL)
    (gradient,) = torch.autograd.grad(y.pow(2).sum(), [model.effects["cubic_stiffness"].parametrizations.k3.original])
    step = 1e-3  # central difference: truncation O(step^2) ~ 1e-6, solver noise rtol/step ~ 1e-4 relative
    with torch.no_grad():
        up = simulate(model.assign(**{"cubic_stiffness.k3": 0.5 + step}), t, u, knots=knots, **TOL).pow(2).sum()
        down = simulate(model.assign(**{"cubic_stiffness.k3": 0.5 - step}), t, u, knots=knots, **TOL).pow(2).sum()
    assert float(gradient) == pytest.approx(float(up - down) / (2 * step), rel=1e-3)


def test_effects_with_memory_append_their_states_after_the_physics():
    model = Oscillator() + CubicStiffness(1.0) + Hysteresis(k=1.0, gamma=2.0) + InputLag(tau=0.1)
    assert model.state_names == ("position", "velocity", "hysteresis.z", "input_lag.u_lag")
    assert torch.equal(model.initial_state(2), torch.zeros(2, 4))
    assert "state hysteresis.z ([x]): hysteretic displacement, starts at 0" in model.describe()
    x0 = torch.tensor([[0.3, -0.1]])
    assert torch.equal(complete_state(model, x0, 1), torch.tensor([[0.3, -0.1, 0.0, 0.0]]))  # the base's states
    whole = torch.ones(1, 4)
    assert complete_state(model, whole, 1) is whole
    with pytest.raises(ValueError, match="x0 has 5 states, but .* has 4"):
        complete_state(model, torch.ones(1, 5), 1)
    with pytest.raises(TypeError, match="carries effect states .*call derivative"):
        model.acceleration(torch.zeros(()), torch.zeros(3), torch.zeros(3), torch.zeros(3))


def test_a_base_state_is_completed_wherever_it_is_passed(grid):
    """simulate from the base's x0 equals simulate from the whole state with the effect's state at its initial."""
    u = pseudorandom(grid, 1.0, seed=2)
    model = Oscillator(zeta=0.3, omega0=2.0) + Hysteresis(k=1.0, gamma=2.0, delta=0.5)
    with torch.no_grad():
        short = simulate(model, grid, u, torch.tensor([[0.2, 0.0]]), solver=RK4(substeps=2))
        whole = simulate(model, grid, u, torch.tensor([[0.2, 0.0, 0.0]]), solver=RK4(substeps=2))
    assert torch.equal(short, whole)


def test_the_input_lag_is_off_at_zero_and_for_a_negative_tau(grid):
    u = pseudorandom(grid, 1.0, seed=3)
    base = Oscillator(zeta=0.3, omega0=2.0)
    with torch.no_grad():
        exact = simulate(base, grid, u)
        for tau in (0.0, -0.5):
            lagged = simulate(base + InputLag(tau=tau), grid, u, solver=RK4(substeps=8))
            torch.testing.assert_close(lagged, exact, rtol=0, atol=1e-7)  # RK4 at h/8 against the exact path


def test_the_input_lag_needs_a_single_input():
    class TwoInputs(Oscillator):
        input_dim = 2

    with pytest.raises(TypeError, match="input_lag lags a single input; TwoInputs has 2"):
        TwoInputs() + InputLag()


def test_an_effect_with_states_but_no_dynamics_is_refused_by_name():
    class Forgetful(AbstractEffect):
        name = "forgetful"
        own_states = (EffectState("w"),)

    with pytest.raises(NotImplementedError, match="forgetful declares own_states and must implement state_rate"):
        simulate(Oscillator() + Forgetful(), torch.arange(5.0), torch.zeros(1, 5, 1), solver=RK4(substeps=1))


def test_the_memory_effects_are_bounded_at_what_the_sampling_resolves_unless_given():
    t = torch.linspace(0.0, 1.0, 11)
    record = Record(t, torch.zeros(11, 1), (t**2)[:, None], "r")  # the largest change over a sample: 0.19
    assert DynamicFriction().bounds([record]) == {"zc": (pytest.approx(0.095), float("inf"))}
    zc, = (value for name, value in DynamicFriction().starts([record])[0].items() if name == "zc")
    assert zc > 0.095  # the start lies inside the bound
    assert DynamicFriction(zc=0.01).bounds([record]) == {}  # the user's own value is not bounded
    assert Hysteresis(gamma=1.0).bounds([record]) == {}  # a loop shape the user chose
    limit = 2 / 0.19  # twice over the largest change over a sample (below the RMS of y here)
    bounds = Hysteresis().bounds([record])
    assert sorted(bounds) == ["delta", "gamma"]
    assert all(value == pytest.approx((-limit, limit)) for value in bounds.values())
    assert all(abs(start["gamma"]) < limit and abs(start["delta"]) < limit for start in Hysteresis().starts([record]))


def test_a_coulomb_frictions_width_is_bounded_at_the_speeds_the_samples_resolve():
    """The smoothing velocity's floor is SIGN_RESOLUTION of the output's largest rate (0.19 over 0.1 s here); a ranking
    fit holds every effect's bounds on its learnable parameters, widened to take a start beyond them."""
    from torchpaml._diagnostics.ranking.refits import effect_bounds
    from torchpaml._physics.effects import SIGN_RESOLUTION

    t = torch.linspace(0.0, 1.0, 11)
    record = Record(t, torch.zeros(11, 1), (t**2)[:, None], "r")
    floor = SIGN_RESOLUTION * 0.19 / 0.1
    assert CoulombFriction().bounds([record]) == {"eps": (pytest.approx(floor), float("inf"))}
    model = Oscillator() + CoulombFriction(eps=0.01)
    assert effect_bounds(model, [record]) == {}  # eps fixed: nothing to bound
    model.set_learnable("coulomb_friction.eps")
    assert effect_bounds(model, [record]) == {"coulomb_friction.eps": (pytest.approx(floor), float("inf"))}
    below = (Oscillator() + CoulombFriction(eps=1e-6)).set_learnable("coulomb_friction.eps")
    assert effect_bounds(below, [record]) == {"coulomb_friction.eps": (pytest.approx(1e-6), float("inf"))}
    assert effect_bounds(Oscillator(), [record]) == {}
