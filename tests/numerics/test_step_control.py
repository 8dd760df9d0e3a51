"""``simulate``'s default RK4 step control (step doubling to ``rtol``) against scipy's DOP853 at rtol 1e-12.

The model is the hard case: the linear oscillator (omega0 = 2 rad/s, sampled at h = 0.1 s, so
h * omega0 = 0.2) plus a cubic stiffness whose force is twice the linear one at the RMS of the linear
response. Tolerance: the error of the returned output (relative RMS) is at most ``rtol``. The oracle
integrates each sample interval on its own, so that the first-order hold's corners fall on its step ends.
"""


import numpy as np
import pytest
import torch

from torchpaml import RK4, Auto
from torchpaml import (AbstractPhysics, CubicStiffness, Oscillator, PhysicalParameter, Positive, ResolutionError,
                       register_parameters, simulate, state_vector)
from torchpaml._signals import multisine
from torchpaml._simulate.step_control import next_substeps, output_gap, simulate_to_tolerance

from oracles import oracle


@pytest.fixture(scope="module")
def hard():
    """(model, t, u, the DOP853 reference output)."""
    t = torch.arange(1500, dtype=torch.float64) * 0.1
    u = multisine(t, 1.0, [0.05, 0.1, 0.2, 0.3, 0.5], seed=0)
    linear = Oscillator(zeta=0.2, omega0=2.0, gain=4.0)
    with torch.no_grad():
        rms = float(simulate(linear, t, u).square().mean().sqrt())
        k3 = 2 * 4.0 / rms**2
        model = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(k3)

        def rate(state, drive):  # x'' = gain u - 2 zeta omega0 x' - omega0^2 x - k3 x^3, written out by hand
            x, v = state
            return np.array([v, 4.0 * drive - 2 * 0.2 * 2.0 * v - 2.0**2 * x - k3 * x**3])

        reference = oracle(model, t, u, rate=rate)
    return model, t, u, reference


def relative_error(y, reference):
    return float((y - reference).norm() / reference.norm())


@pytest.mark.parametrize("rtol", [None, 1e-5])
def test_the_default_meets_its_tolerance_on_a_hard_nonlinearity(hard, rtol):
    model, t, u, reference = hard
    with torch.no_grad():
        y = simulate(model, t, u, solver=None if rtol is None else Auto(rtol=rtol))
        one_substep = simulate(model, t, u, solver=RK4(substeps=1))
    assert relative_error(y, reference) <= (1e-3 if rtol is None else rtol)
    assert relative_error(one_substep, reference) > 10 * relative_error(y, reference)  # the check did refine


def test_a_fixed_step_is_taken_as_given_and_calling_the_model_simulates_by_the_default(hard):
    model, t, u, _ = hard
    with torch.no_grad():
        fixed = simulate(model, t, u, solver=RK4(substeps=1))
        called = model(t, u)
        default = simulate(model, t, u)
        finer = simulate(model, t, u, solver=RK4(substeps=2))
    assert torch.equal(default, called)
    assert not torch.equal(fixed, finer) and not torch.equal(fixed, called)


def test_the_gradient_of_the_default_matches_central_differences(hard):
    model, t, u, _ = hard
    k3 = model.effects["cubic_stiffness"].parametrizations.k3.original
    model.zero_grad()
    simulate(model, t, u).square().sum().backward()
    step = 1e-6 * float(k3.detach().abs())
    with torch.no_grad():
        k3 += step
        plus = simulate(model, t, u).square().sum()
        k3 -= 2 * step
        minus = simulate(model, t, u).square().sum()
        k3 += step
    assert float(k3.grad) == pytest.approx(float((plus - minus) / (2 * step)), rel=1e-6)


def test_a_tolerance_beyond_reach_raises_a_resolution_error_naming_the_fixes(hard):
    model, t, u, _ = hard
    with pytest.raises(ResolutionError, match=r"RK4 cannot meet rtol=1e-15.*Loosen rtol, fix the step with "
                                              r"RK4\(substeps=N\), integrate stiff physics with TRBDF2\(\), or use "
                                              r"Dopri5\(\)"):
        simulate(model, t, u, solver=RK4(rtol=1e-15))


@pytest.mark.parametrize("substeps", ["fast", 0, 2.5])
def test_a_step_that_is_not_auto_or_a_whole_number_is_refused(hard, substeps):
    model, t, u, _ = hard
    with pytest.raises(ValueError, match=r"substeps must be 'auto' \(to rtol\) or a whole number"):
        RK4(substeps=substeps)


class FastTank(AbstractPhysics):
    """A tank drained fast against the sampling: x' = -k x - x^3 + u."""

    state_names = ("level",)

    def __init__(self, k: float):
        super().__init__()
        register_parameters(self, [PhysicalParameter("k", k, "1/s", Positive(), "outflow rate")], ())

    def derivative(self, t, x, u):
        level = x[..., 0]
        return state_vector([-self.k * level - level**3 + u[..., 0]])

    def output(self, x, u):
        return x


def test_a_rate_too_fast_for_one_substep_is_integrated_at_more():
    t = torch.arange(300, dtype=torch.float64) * 0.1
    u = multisine(t, 1.0, [0.05, 0.1, 0.2], seed=1)
    physics = FastTank(k=40.0)  # k h = 4: RK4 at one substep per sample is unstable
    with torch.no_grad():
        reference = oracle(physics, t, u)
        y = simulate(physics, t, u)
    assert relative_error(y, reference) <= 1e-3


def test_step_doubling_arithmetic():
    assert output_gap(torch.ones(4), torch.ones(4)) == 0.0
    assert output_gap(torch.tensor([1.0, 0.0]), torch.tensor([0.0, 0.0])) == 0.0  # a zero output has no error
    assert output_gap(torch.tensor([1.1]), torch.tensor([1.0])) == pytest.approx(0.1)
    assert next_substeps(1, 1e-3, 1e-3) == 2  # at least doubles
    assert next_substeps(2, 16 * 5e-4, 1e-3) == 4  # fourth order: a gap 16x half the target needs twice the substeps
    assert next_substeps(2, 256 * 5e-4, 1e-3) == 8


@pytest.mark.parametrize("first_gap_passes", [False, True])
def test_with_a_gradient_the_accepted_step_is_simulated_once_with_it(first_gap_passes):
    """Step doubling under grad mode: a fine run that the order predicts to pass (after a first gap) is recorded as it
    runs; a first fine run that passes is simulated once more with the gradient. No step is simulated twice but
    that one, and the output returned carries the gradient."""
    theta = torch.tensor(1.0, dtype=torch.float64, requires_grad=True)
    error = 1e-4 if first_gap_passes else 0.5  # the output at m substeps: theta (1 + error / m^4)
    calls = []

    def run(m):
        calls.append((m, torch.is_grad_enabled()))
        return (theta * (1 + error / m**4)).reshape(1)

    y, m = simulate_to_tolerance(run, 1, 1e-3, 0.1)
    assert y.requires_grad
    if first_gap_passes:
        assert calls == [(1, False), (2, False), (2, True)] and m == 2
    else:
        assert [c for c, _ in calls] == sorted({c for c, _ in calls})  # each step once
        assert calls[-1][1] and not any(grad for _, grad in calls[:-1]) and m == calls[-1][0]
