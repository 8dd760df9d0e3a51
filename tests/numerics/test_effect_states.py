"""Effects with their own states, integrated with the physics: against scipy's DOP853 (integrating the physics'
closed-form rate, lambdified), and their gradients.

The models: the oscillator (zeta 0.2, omega0 2 rad/s, gain 4, sampled at h = 0.05 s) plus each library effect
with memory, strong enough to change the output by tens of per cent. Tolerances: RK4 to ``rtol`` (the
default, 1e-3, relative RMS of the output) against DOP853 at rtol 1e-12; gradients against central
differences of step 1e-6 (error O(1e-12) relative, plus Newton's 1e-9), to 1e-5.

LuGre's bristle damping (tau1 > 0) puts |v| into the force itself, a corner of the vector field that the
shooting's start sensitivities (central differences, :mod:`torchpaml._simulate.shooting`) straddle: there the
gradient is 1e-4 off (measured), so the gradient check takes tau1 = 0 (learned, so its column is checked too).
"""

import pytest
import torch

from torchpaml import RK4
from torchpaml import DynamicFriction, Hysteresis, InputLag, Oscillator, fit_physics, Record, simulate
from torchpaml._signals import multisine

from oracles import closed_form_rate, oracle

MODELS = {
    "hysteresis": lambda: Hysteresis(k=2.0, gamma=1.0, delta=0.5),
    "dynamic_friction": lambda: DynamicFriction(sigma0=5.0, zc=0.1, ratio=1.5, vs=0.5, tau1=0.0,
                                                learn=("sigma0", "zc", "ratio", "tau1")),
    "input_lag": lambda: InputLag(tau=0.3),
}


@pytest.fixture(scope="module")
def record():
    t = torch.arange(400, dtype=torch.float64) * 0.05
    return t, multisine(t, 1.0, [0.1, 0.2, 0.35, 0.6], seed=0)


def model(name):
    return Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + MODELS[name]()


def relative_error(y, reference):
    return float((y - reference).norm() / reference.norm())


@pytest.mark.parametrize("name", sorted(MODELS))
def test_the_default_simulation_meets_its_tolerance_against_dop853(name, record):
    t, u = record
    physics = model(name)
    reference = oracle(physics, t, u, rate=closed_form_rate(physics))
    with torch.no_grad():
        y, base = simulate(physics, t, u), simulate(Oscillator(zeta=0.2, omega0=2.0, gain=4.0), t, u)
    assert relative_error(base, reference) > 0.1  # the effect acts
    assert relative_error(y, reference) < 1e-3


@pytest.mark.parametrize("name", sorted(MODELS))
def test_gradients_match_central_differences(name, record):
    t, u = record
    physics = model(name)
    names = [n for n in physics.learnable_names() if n.startswith(f"{name}.")]
    weights = torch.randn(len(t), generator=torch.Generator().manual_seed(1), dtype=torch.float64)

    def loss():
        return (simulate(physics, t, u, solver=RK4(substeps=4))[0, :, 0] * weights).sum()

    physics.zero_grad()
    loss().backward()
    owners = {n: physics._owner(n) for n in names}
    for n, (owner, leaf) in owners.items():
        raw = getattr(owner.parametrizations, leaf).original
        step = 1e-6 * max(1.0, abs(float(raw)))
        with torch.no_grad():
            raw += step
            up = float(loss())
            raw -= 2 * step
            down = float(loss())
            raw += step
        assert float(raw.grad) == pytest.approx((up - down) / (2 * step), rel=1e-5, abs=1e-8), n


@pytest.mark.slow  # 15 to 35 s: the slow lane (make test-all)
def test_the_step_check_resolves_a_fast_effect_state():
    """A lag of half a sample interval on a noiseless record: at one RK4 step per sample the output is 6e-5 off
    (measured; the oscillator smooths the lag state's own error), far above what the noiseless record leaves, so
    the fit's step check raises the substeps until the output no longer depends on them, and recovers the lag."""
    t = torch.arange(600, dtype=torch.float64) * 0.05
    u = multisine(t, 1.0, [0.1, 0.3, 0.7, 1.2, 2.0], seed=2)
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + InputLag(tau=0.025)
    y = oracle(truth, t, u)
    with torch.no_grad():
        assert relative_error(simulate(truth, t, u, solver=RK4(substeps=1)), y) > 1e-5
    physics = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + InputLag(tau=0.05)
    estimate = fit_physics(physics, Record(t, u[0], y[0]))
    assert estimate.solver.substeps > 1
    assert float(physics.physical_parameters()["input_lag.tau"]) == pytest.approx(0.025, rel=1e-3)
