"""fit_least_squares and simulate_rows: batched parameter rows, the finite-difference Jacobian, recovery."""

import copy

import pytest
import torch

from torchpaml import Experiment, Oscillator, SimulationError, simulate
from torchpaml.fit.least_squares import fit_least_squares, raw_parameters, simulate_rows
from torchpaml.physics import CubicStiffness, OutputSaturation
from torchpaml.signals import pseudorandom, time_grid


@pytest.fixture
def record():
    """Noise-free Duffing data: 20 s at 20 Hz."""
    t = time_grid(20.0, 0.05)
    u = pseudorandom(t, 1.0, seed=3)
    true = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CubicStiffness(2.0)
    return Experiment(t, u[0], simulate(true, t, u, method="rk4")[0].detach())


def model(**values):
    m = Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain")) + CubicStiffness()
    return m.assign(**values)


def test_rows_equal_one_simulation_per_parameter_set(record):
    """Each batch row with its own (raw) parameters equals assigning them and simulating alone, to round-off."""
    m = model() + OutputSaturation()  # an output map too: batched parameters must broadcast there as well
    names = ["zeta", "cubic_stiffness.k3", "output_saturation.s"]
    sets = [(0.3, 1.0, 0.2), (0.6, -0.5, 0.0), (0.2, 2.0, 0.5)]
    rows = []
    for values in sets:
        m.assign(**dict(zip(names, values)))
        rows.append(torch.stack([v.detach().clone() for v in raw_parameters(m, names).values()]))
    batched = simulate_rows(m, names, torch.stack(rows), record.t, record.u[None])
    for row, values in zip(batched, sets):
        m.assign(**dict(zip(names, values)))
        alone = m(record.t, record.u[None], method="rk4")[0].detach()
        torch.testing.assert_close(row, alone, rtol=0, atol=1e-12)


def test_jacobian_matches_autograd(record):
    """The central-difference Jacobian at the optimum equals the autograd one (same RK4 grid) to 1e-6 relative."""
    m = model(zeta=0.25, omega0=1.9, gain=3.5, **{"cubic_stiffness.k3": 1.5})
    m.set_learnable("cubic_stiffness.k3")
    fit = fit_least_squares(m, record, max_nfev=1)
    raw = list(raw_parameters(m, m.learnable_names()).values())
    y = m(record.t, record.u[None], method="rk4")[0, :, 0]
    scale = float(record.y.norm())
    rows = [torch.autograd.grad(-y[i] / scale, raw, retain_graph=True) for i in range(0, len(y), 7)]
    exact = torch.stack([torch.stack(g) for g in rows])
    torch.testing.assert_close(fit.jacobian[::7], exact, rtol=1e-6, atol=1e-9 * float(exact.abs().max()))


def test_recovers_the_generating_parameters(record):
    """Noise-free data from a start 25-50 % off: the true values to 1e-6 and a mismatch below 1e-8."""
    m = model()
    fit = fit_least_squares(m, record)
    assert fit.mismatch < 1e-8
    for name, true in {"zeta": 0.2, "omega0": 2.0, "gain": 4.0, "cubic_stiffness.k3": 2.0}.items():
        assert fit.parameters[name] == pytest.approx(true, rel=1e-6)
    assert fit.jacobian.shape == (len(record.t), 4)


def test_linear_physics_uses_the_exact_simulator(record):
    """Linear physics: rows are simulated exactly, and the fit matches the L-BFGS fit of fit_physics."""
    from torchpaml import fit_physics

    lm = Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain"))
    bfgs = copy.deepcopy(lm)
    fit = fit_least_squares(lm, record)
    reference = fit_physics(bfgs, record.t, record.u[None], record.y[None])
    assert fit.mismatch == pytest.approx(reference.mismatch, rel=1e-6)


def test_a_start_that_blows_up_is_an_error_that_names_it(record):
    m = model(**{"cubic_stiffness.k3": -60.0})  # softening spring far past its turning point: x runs away
    with pytest.raises(SimulationError, match="blew up"):
        fit_least_squares(m, record)


def test_no_learnable_parameter_is_an_error(record):
    with pytest.raises(ValueError, match="no learnable parameter"):
        fit_least_squares(Oscillator(learn=()), record)
