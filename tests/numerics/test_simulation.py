"""Simulators against oracles: scipy's lsim and solve_ivp, the analytic step response, and each other.

Tolerances: the exact path is exact up to float64 round-off (matrix exponential, ~1e-13 observed);
the ODE path is held to 1e-8 relative at rtol=1e-10 (dopri5's global error is a small multiple of
rtol on these horizons).
"""

import math

import numpy as np
import pytest
import torch
from scipy import integrate, signal

from torchpaml import Auto, Dopri5, Exact, RK4
from torchpaml import Oscillator, Pendulum, simulate
from torchpaml._signals import pseudorandom, pseudorandom_knots, sine


def _relative(a, b):
    a, b = a.detach(), b.detach()
    return float((a - b).abs().max() / b.abs().max())


@pytest.mark.parametrize("zeta", [0.2, 1.0, 2.5])
def test_exact_agrees_with_torchdiffeq_to_1e8(grid, zeta):
    physics = Oscillator(zeta=zeta, omega0=2.0, gain=1.3)
    u = pseudorandom(grid, 4.0, batch=2, seed=1)
    exact = simulate(physics, grid, u, solver=Exact())
    ode = simulate(physics, grid, u, solver=Dopri5(rtol=1e-10, atol=1e-12), knots=pseudorandom_knots(grid))
    assert _relative(exact, ode) <= 1e-8


def test_exact_matches_scipy_lsim_with_initial_state(grid):
    physics = Oscillator(zeta=0.3, omega0=2.0)
    u = sine(grid, 2.0, 1.3)
    x0 = torch.tensor([[0.4, -0.7]])
    y = simulate(physics, grid, u, x0)
    A, B, C, D = (m.detach().numpy() for m in physics.state_space())
    _, ref, _ = signal.lsim((A, B, C, D), u[0, :, 0].numpy(), grid.numpy(), X0=x0[0].numpy(), interp=True)
    np.testing.assert_allclose(y[0, :, 0].detach().numpy(), ref, rtol=0, atol=1e-11 * np.abs(ref).max())


def test_exact_matches_analytic_step_response(grid):
    # underdamped step response of x'' + 2 z w x' + w^2 x = u, u = 1 (a constant input is piecewise linear)
    z, w = 0.25, 2.0
    wd = w * math.sqrt(1 - z**2)
    t = grid
    analytic = (1 - torch.exp(-z * w * t) * (torch.cos(wd * t) + z * w / wd * torch.sin(wd * t))) / w**2
    y = simulate(Oscillator(zeta=z, omega0=w), t, torch.ones(1, len(t), 1))
    assert _relative(y[0, :, 0], analytic) < 1e-12


def test_pendulum_ode_matches_scipy_solve_ivp(grid):
    physics = Pendulum(zeta=0.5, omega0=2.0)
    u = pseudorandom(grid, 6.0, seed=3)
    knots = pseudorandom_knots(grid)
    y = simulate(physics, grid, u, solver=Auto(rtol=1e-10))
    values = u[0, :, 0].numpy()

    def f(t, s):
        ut = np.interp(t, grid.numpy(), values)
        return [s[1], ut - 2 * 0.5 * 2.0 * s[1] - 4.0 * np.sin(s[0])]

    ref = integrate.solve_ivp(f, (0, float(grid[-1])), [0, 0], t_eval=grid.numpy(), rtol=1e-11, atol=1e-13,
                              method="DOP853", max_step=0.05)
    np.testing.assert_allclose(y[0, :, 0].detach().numpy(), np.sin(ref.y[0]), atol=1e-7)


def test_exact_gradient_is_finite_at_critical_damping(grid):
    physics = Oscillator(zeta=1.0)
    loss = simulate(physics, grid, sine(grid, 1.0, 1.0)).square().sum()
    loss.backward()
    grad = physics.parametrizations.zeta.original.grad
    assert torch.isfinite(grad) and grad.abs() > 0


def test_gradcheck_exact_simulator_in_parameters_and_input():
    t = torch.arange(30, dtype=torch.float64) * 0.05

    def run(raw_zeta, raw_gain, u):
        physics = Oscillator(learn=("zeta", "gain"))
        return torch.func.functional_call(
            physics, {"parametrizations.zeta.original": raw_zeta, "parametrizations.gain.original": raw_gain}, (t, u)
        )

    u = torch.randn(1, 30, 1, requires_grad=True)
    args = (torch.tensor(-0.4, requires_grad=True), torch.tensor(1.2, requires_grad=True), u)
    assert torch.autograd.gradcheck(run, args)


def test_gradcheck_ode_simulator_in_parameters():
    t = torch.arange(20, dtype=torch.float64) * 0.05
    u = sine(t, 2.0, 1.0)

    def run(raw_zeta):
        physics = Pendulum()
        return torch.func.functional_call(physics, {"parametrizations.zeta.original": raw_zeta}, (t, u),
                                          {"solver": RK4()})

    assert torch.autograd.gradcheck(run, (torch.tensor(-0.5, requires_grad=True),))


def test_adjoint_gradient_matches_direct_backprop(grid):
    t = grid[:60]
    u = sine(t, 2.0, 1.0)
    grads = []
    for adjoint in (False, True):
        physics = Pendulum()
        simulate(physics, t, u, solver=Dopri5(rtol=1e-8, atol=1e-10, adjoint=adjoint)).square().sum().backward()
        grads.append(physics.parametrizations.zeta.original.grad)
    assert torch.allclose(grads[0], grads[1], rtol=1e-5)  # both within solver tolerance of the truth


def test_zero_order_hold_matches_scipy_lsim_and_rk4_converges_to_it():
    # the input held constant between samples (a DAC): the exact path against scipy's lsim(interp=False), from a
    # state not at rest, to 1e-12; RK4 on the same hold (a composed model at zero strength takes the RK4 path)
    # converges to it at fourth order: 8 substeps divide its error by 8^4 = 4096 (held to > 2000)
    import numpy as np
    from scipy.signal import lsim

    from torchpaml._physics import CubicStiffness

    t = torch.arange(400, dtype=torch.float64) * 0.1
    u = (torch.sin(0.7 * t) + (torch.arange(400) % 7 == 0).double())[None, :, None]  # steps: the holds differ
    physics = Oscillator(zeta=0.3, omega0=1.5, gain=2.0)
    x0 = torch.tensor([[0.3, -0.2]], dtype=torch.float64)
    A, B, C, D = (m.detach().numpy() for m in physics.state_space())
    with torch.no_grad():
        exact = simulate(physics, t, u, x0, hold="zoh")[0, :, 0]
        first_order = simulate(physics, t, u, x0)[0, :, 0]
        errors = [float((simulate(physics + CubicStiffness(0.0), t, u, x0, solver=RK4(substeps=m), hold="zoh")[0, :, 0]
                         - exact).abs().max()) for m in (1, 8)]
    _, oracle, _ = lsim((A, B, C, D), u[0, :, 0].numpy(), t.numpy(), X0=x0[0].numpy(), interp=False)
    assert np.abs(exact.numpy() - oracle).max() < 1e-12
    assert float((exact - first_order).abs().max()) > 0.02  # the hold matters on this input (0.049)
    assert errors[0] < 1e-5 and errors[0] / errors[1] > 2000
    with pytest.raises(ValueError, match="hold='zoh' is simulated by the exact path and by the fixed-step solvers"):
        simulate(physics + CubicStiffness(0.0), t, u, x0, solver=Dopri5(), hold="zoh")


@pytest.mark.parametrize("zeta, hold", [(0.3, "foh"), (1.0, "foh"), (0.3, "zoh")])  # 1.0: critical damping
def test_exact_jacobian_matches_reverse_mode_autograd(zeta, hold):
    # the exact path's Jacobian comes from the discretisation's sensitivity recurrence (one filter run for every
    # column); the oracle is reverse-mode autograd through the exact simulation. Two records, not at rest, and the
    # initial state's columns, whose oracle is the free response C Phi^k e_i
    from torch.func import functional_call

    from torchpaml._signals import multisine
    from torchpaml._simulate import output_jacobian, raw_parameters

    t = torch.arange(400, dtype=torch.float64) * 0.05
    u = torch.cat([multisine(t, 1.0, [0.05, 0.1, 0.3], seed=seed) for seed in (0, 1)])
    physics = Oscillator(zeta=zeta, omega0=1.7, gain=2.0, learn=("zeta", "omega0", "gain"))
    x0 = torch.tensor([[0.2, -0.1], [0.0, 0.3]], dtype=torch.float64)
    y, J = output_jacobian(physics, physics.learnable_names(), t, u, x0, initial_state=True, hold=hold)
    raw = raw_parameters(physics, physics.learnable_names())

    def output(*values):  # the raw parameters, then x0
        return functional_call(physics, dict(zip(raw, values[:-1], strict=True)), (t, u, values[-1]),
                               {"hold": hold})[..., 0]

    expected = torch.autograd.functional.jacobian(output, (*(v.detach() for v in raw.values()), x0))
    oracle = torch.stack(expected[:3], dim=-1)  # (record, time, parameter)
    free = torch.stack([torch.stack([expected[3][b, :, b, i] for b in range(2)]) for i in range(2)], dim=-1)
    scale = float(oracle.abs().max())
    with torch.no_grad():
        # the same transfer functions, recursed per output (the forward) or once for all states (the Jacobian's):
        # equal to rounding, 1.2e-14 at most here on outputs of order 1
        assert torch.allclose(y, physics(t, u, x0, hold=hold), rtol=0, atol=1e-13)
    assert float((J[:, :, 0, :3] - oracle).abs().max()) < 1e-9 * scale
    assert float((J[:, :, 0, 3:] - free).abs().max()) < 1e-9 * float(free.abs().max())
