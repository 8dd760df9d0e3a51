"""The parallel-in-time RK4 engine against oracles: scipy's DOP853, its own sequential run, its order, gradients.

Tolerances:
- RK4's global error on a damped oscillator is about $(h\\omega)^4/(120\\,\\zeta)$ relative (local error
  $(h\\omega)^5/120$ per step, accumulated over the memory $1/(\\zeta\\omega)$); at $h\\omega_0 = 0.2$, $\\zeta = 0.2$
  that is 6.7e-5, and the test allows 2e-4 for the stiffening of the cubic term;
- multiple shooting converges to the sequential RK4 solution: Newton stops at a defect of 1e-7 (1e-9 when
  gradients are taken) and applies its last update linearly, so they agree to O(1e-14), held to 1e-10;
- gradients use central differences of the starts (error ~1e-10) and are compared with central
  differences of the whole simulation at rtol 1e-6.
"""

import numpy as np
import pytest
import torch
from scipy.integrate import solve_ivp

from torchpaml import Dopri5, RK4
from torchpaml import CubicStiffness, Oscillator, QuadraticDamping, SimulationError, multisine, simulate, time_grid
from torchpaml.engine import WarmStart


def _duffing(zeta=0.2, k3=2.0):
    return Oscillator(zeta=zeta, omega0=2.0, gain=4.0, learn=("zeta",)) + CubicStiffness(k3)


def _relative(a, b):
    return float((a - b).abs().max() / b.abs().max())


@pytest.fixture(scope="module")
def drive():
    t = time_grid(40.0, 0.1)  # h * omega0 = 0.2
    return t, multisine(t, 1.0, [0.05, 0.1, 0.2, 0.3], seed=0)


@pytest.fixture(scope="module")
def reference(drive):
    """``_duffing()``'s output by scipy's DOP853 at rtol 1e-12, one sample interval at a time (the input is linear
    inside each, so no kink is stepped over): an independent implementation, (1, time, 1)."""
    t, u = (a.numpy().ravel() for a in drive)

    def field(s, state, k):
        slope = (u[k + 1] - u[k]) / (t[k + 1] - t[k])
        x, v = state
        return [v, -2 * 0.2 * 2.0 * v - 4.0 * x - 2.0 * x**3 + 4.0 * (u[k] + slope * (s - t[k]))]

    states = [np.zeros(2)]
    for k in range(len(t) - 1):
        end = solve_ivp(field, (t[k], t[k + 1]), states[-1], method="DOP853", rtol=1e-12, atol=1e-14, args=(k,))
        states.append(end.y[:, -1])
    return torch.tensor(np.array(states)[:, :1])[None]


def test_the_oracle_is_the_model():
    """The hand-written field of ``reference`` is ``_duffing()``'s derivative."""
    x = torch.tensor([[0.3, -0.7], [-1.1, 0.4]], dtype=torch.float64)
    u = torch.tensor([[0.5], [-0.2]], dtype=torch.float64)
    expected = torch.stack([x[:, 1], -0.8 * x[:, 1] - 4.0 * x[:, 0] - 2.0 * x[:, 0] ** 3 + 4.0 * u[:, 0]], dim=1)
    assert torch.allclose(_duffing().derivative(torch.zeros(2), x, u), expected, rtol=1e-14)


def test_rk4_agrees_with_dop853_within_its_error_bound(drive, reference):
    t, u = drive
    with torch.no_grad():
        y = simulate(_duffing(), t, u, solver=RK4())
    assert _relative(y, reference) < 2e-4


def test_rk4_converges_at_fourth_order(drive, reference):
    t, u = drive
    with torch.no_grad():
        errors = [_relative(simulate(_duffing(), t, u, solver=RK4(substeps=m)), reference) for m in (1, 2)]
    assert 12 < errors[0] / errors[1] < 20  # 2^4 = 16


@pytest.mark.parametrize("segment", [1, 4, 16])
def test_multiple_shooting_equals_sequential_rk4(drive, segment):
    t, u = drive
    with torch.no_grad():
        sequential = simulate(_duffing(), t, u, solver=RK4(segment=10**6))
        parallel = simulate(_duffing(), t, u, solver=RK4(segment=segment))
    assert _relative(parallel, sequential) < 1e-10


def test_rows_are_independent(drive):
    t, _ = drive
    u = torch.cat([multisine(t, a, [0.05, 0.1, 0.2], seed=1) for a in (0.5, 1.0, 2.0)])
    with torch.no_grad():
        together = simulate(_duffing(), t, u, solver=RK4())
        alone = torch.cat([simulate(_duffing(), t, u[i : i + 1], solver=RK4()) for i in range(3)])
    assert _relative(together, alone) < 1e-12


def _central_difference(model_of, value, t, u, weight, step=1e-6):
    with torch.no_grad():
        plus = (simulate(model_of(value + step), t, u, solver=RK4()) * weight).sum()
        minus = (simulate(model_of(value - step), t, u, solver=RK4()) * weight).sum()
    return float((plus - minus) / (2 * step))


@pytest.mark.parametrize("name", ["zeta", "k3"])
def test_reverse_mode_gradient_matches_central_differences(drive, name):
    t, u = drive
    weight = torch.randn(u.shape, generator=torch.Generator().manual_seed(0))
    model = _duffing()
    model.set_learnable("zeta", "cubic_stiffness.k3")
    (simulate(model, t, u, solver=RK4()) * weight).sum().backward()
    key = "zeta" if name == "zeta" else "cubic_stiffness.k3"
    owner, leaf = model._owner(key)
    raw_grad = float(getattr(owner.parametrizations, leaf).original.grad)
    value = model.physical_parameters()[key]
    chain = value if name == "zeta" else 1.0  # zeta = exp(raw): d/draw = zeta d/dzeta
    fd = _central_difference(lambda v: _duffing(**{name: v}), value, t, u, weight)
    assert raw_grad == pytest.approx(chain * fd, rel=1e-6)


def test_gradient_in_initial_state_matches_central_differences(drive):
    t, u = drive
    x0 = torch.tensor([[0.3, -0.2]], requires_grad=True)
    weight = torch.randn(u.shape, generator=torch.Generator().manual_seed(1))
    (simulate(_duffing(), t, u, x0, solver=RK4()) * weight).sum().backward()
    with torch.no_grad():
        shift = torch.tensor([[1e-6, 0.0]])
        plus = (simulate(_duffing(), t, u, x0 + shift, solver=RK4()) * weight).sum()
        minus = (simulate(_duffing(), t, u, x0 - shift, solver=RK4()) * weight).sum()
    assert float(x0.grad[0, 0]) == pytest.approx(float((plus - minus) / 2e-6), rel=1e-6)


@pytest.mark.parametrize("segment", [1, 16])
def test_forward_mode_equals_reverse_mode(drive, segment):
    """Also with one step per segment, where tangents leaking through Newton's iterations showed (3e-6 at 2 steps)."""
    t, u = drive
    model = _duffing()
    key = "base.parametrizations.zeta.original"
    raw = model.base.parametrizations.zeta.original.detach().clone()

    def output(r):
        return torch.func.functional_call(model, {key: r}, (t, u), {"solver": RK4(segment=segment)})

    _, tangent = torch.func.jvp(output, (raw,), (torch.ones_like(raw),))
    cotangent = torch.randn(u.shape, generator=torch.Generator().manual_seed(2))
    (reverse,) = torch.autograd.grad((output(raw.requires_grad_()) * cotangent).sum(), raw)
    assert float((tangent * cotangent).sum()) == pytest.approx(float(reverse), rel=1e-9)


def test_gradcheck_in_parameter_and_input():
    t = torch.arange(40, dtype=torch.float64) * 0.1
    u = multisine(t, 1.0, [0.1, 0.3], seed=3).requires_grad_()

    def run(raw_zeta, u):
        return torch.func.functional_call(_duffing(), {"base.parametrizations.zeta.original": raw_zeta}, (t, u),
                                          {"solver": RK4(segment=8)})

    # fast mode: the Jacobian against central differences along random directions, one pair of runs per input
    assert torch.autograd.gradcheck(run, (torch.tensor(-1.5, requires_grad=True), u), fast_mode=True)


@pytest.mark.slow  # about 11 s: the slow lane (make test-all), to keep make test under 3 minutes
def test_non_uniform_time_is_simulated_by_the_same_engine(drive):
    t, u = drive
    keep = torch.arange(len(t)) % 3 != 2  # every third sample missing
    t, u = t[keep], u[:, keep]
    with torch.no_grad():
        reference = simulate(_duffing(), t, u, solver=Dopri5(rtol=1e-10, atol=1e-12), knots=t)
        y = simulate(_duffing(), t, u, solver=RK4(substeps=2))
    assert _relative(y, reference) < 2e-4


def test_unstable_parameters_raise_a_simulation_error(drive):
    t, u = drive
    unstable = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(-5.0)  # softening: escapes to infinity
    with pytest.raises(SimulationError, match="blew up"), torch.no_grad():
        simulate(unstable, t, 3 * u, solver=RK4())


def test_a_blow_up_late_in_a_long_record_is_reported_from_newtons_settled_starts(monkeypatch):
    """Negative quadratic damping is harmless at small speeds and runs away at large ones: a drive that grows only in
    the last tenth blows the solution up there. Newton settles the starts up to it and raises; lengthening the
    segments (x8 each time) until one sequential segment reaches the blow-up would take five layouts."""
    import torchpaml._simulate.shooting as shooting

    layouts = []

    class Counted(shooting._Layout):
        def __init__(self, *args, **kwargs):
            layouts.append(args[3])
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(shooting, "_Layout", Counted)
    t = time_grid(2000.0, 0.1)
    u = multisine(t, 0.2, [0.05, 0.1, 0.2, 0.3], seed=0) * (1 + 20 * (t > 1800))[None, :, None]
    runaway = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + QuadraticDamping(-0.5)
    with pytest.raises(SimulationError, match="blew up") as error, torch.no_grad():
        simulate(runaway, t, u, solver=RK4(substeps=1))
    assert len(layouts) <= 2  # one lengthening at most (2 -> 16 steps), not the five to sequential stepping
    blown = float(str(error.value).split("t = ")[1].split(" s")[0])
    assert 1800 <= blown <= 2000


def test_a_warm_start_converges_to_the_same_solution(drive):
    from torchpaml._simulate.shooting import solve_shooting

    t, u = drive
    x0 = torch.zeros(1, 2)
    one = RK4(substeps=1)
    cold = solve_shooting(_duffing(k3=2.0), t, u, x0, one)
    warm = solve_shooting(_duffing(k3=2.1), t, u, x0, one, guess=cold.trajectory)  # a neighbour's solution as the guess
    reference = solve_shooting(_duffing(k3=2.1), t, u, x0, one)
    assert _relative(warm.trajectory, reference.trajectory) < 1e-10


class _UserDuffing(torch.nn.Module):
    """``_duffing()`` as a user would write it against the solvers' protocol (:class:`Dynamics`): no linear base,
    and a derivative stacked row-major."""

    state_dim, state_names = 2, ("position", "velocity")

    def linear_base(self):
        return None

    def derivative(self, t, x, u):
        pos, vel = x[:, 0], x[:, 1]
        return torch.stack([vel, 4.0 * u[:, 0] - 0.8 * vel - 4.0 * pos - 2.0 * pos**3], dim=-1)


def test_any_memory_layout_and_start_give_the_same_solution(drive):
    """The library's composed model (state-major derivative, Newton started from its linear base's
    trajectory) and the same ODE written by a user (row-major, started from x0 held): one solution."""
    from torchpaml._simulate.shooting import simulate_shooting

    t, u = drive
    x0 = torch.tensor([[0.2, -0.1]], dtype=torch.float64)
    with torch.no_grad():
        library = simulate_shooting(_duffing(), t, u, x0, RK4(substeps=1))
        user = simulate_shooting(_UserDuffing(), t, u, x0, RK4(substeps=1))
    assert _relative(user, library) < 1e-10


def test_simulate_warm_starts_from_the_last_solution_and_gives_the_same_output(drive, monkeypatch):
    """``simulate(..., warm=w)``: the second call starts Newton from the first one's states and needs fewer
    sweeps, and neither call's output depends on the warm start (1e-12). The engine's path (a record the compiled
    RK4 takes needs no sweeps)."""
    from torchpaml._simulate import compiled, shooting

    monkeypatch.setattr(compiled, "MIN_STEPS", 10**9)

    t, u = drive
    sweeps = []
    original = shooting._Sweep.__init__

    def counted(self, *args, **kwargs):
        sweeps.append(1)
        original(self, *args, **kwargs)

    warm = WarmStart()
    with torch.no_grad():
        cold = simulate(_duffing(k3=2.1), t, u, solver=RK4())
        simulate(_duffing(k3=2.0), t, u, solver=RK4(), warm=warm)
        shooting._Sweep.__init__ = counted
        try:
            again = simulate(_duffing(k3=2.1), t, u, solver=RK4(), warm=warm)
            warm_sweeps = len(sweeps)
            sweeps.clear()
            simulate(_duffing(k3=2.1), t, u, solver=RK4())
        finally:
            shooting._Sweep.__init__ = original
    assert warm.states.shape == (1, len(t), 2)
    assert _relative(again, cold) < 1e-12
    assert warm_sweeps < len(sweeps)


def test_a_warm_start_that_is_not_a_warm_start_object_is_refused(drive):
    t, u = drive
    with pytest.raises(TypeError, match="warm must be a torchpaml.WarmStart"):
        simulate(_duffing(k3=2.0), t, u, solver=RK4(), warm={})


def test_the_linear_base_of_a_learned_force_is_its_physics():
    """Newton's cold start (the linear base's exact trajectory) reaches through physics + effects and a learned force."""
    from torchpaml import MLPForce, Pendulum
    from torchpaml._residual.mlp import ForceAugmented

    physics = Oscillator(zeta=0.2, omega0=2.0, gain=4.0)
    assert physics.linear_base() is physics
    composed = physics + CubicStiffness(1.0)
    assert composed.linear_base() is composed.base
    assert ForceAugmented(composed, MLPForce()).linear_base() is composed.base
    assert Pendulum().linear_base() is None  # nonlinear: Newton starts from x0 held
