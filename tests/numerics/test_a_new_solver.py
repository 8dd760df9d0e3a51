"""A new solver is one class, defined here and nowhere else: it simulates forward, fits and ranks.

``Heun`` is a fixed-step method in the parallel shooting engine (a :class:`~torchpaml.FixedStep` with a ``sweep``);
``SequentialHeun`` the same method as a plain :class:`~torchpaml.Solver` that steps sample by sample in Python (its
Jacobian comes from central differences of its states). Neither touches any other file of the library.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import pytest
import torch

from torchpaml import Auto, ConstantForce, CubicStiffness, Oscillator, Record, Solver, fit_physics, simulate
from torchpaml.analysis import rank_missing_effects
from torchpaml._simulate.solvers import FixedStep

TRUTH = {"zeta": 0.2, "omega0": 2.0, "gain": 1.5}
K3 = 0.8
#: Measurement noise, a share of the output's spread: the step check resolves the fit to a tenth of it.
NOISE = 1e-3


def _heun_step(physics, t_a, t_c, x, u_a, u_c, h):
    k1 = physics.derivative(t_a, x, u_a)
    k2 = physics.derivative(t_c, x + h * k1, u_c)
    return x + 0.5 * h * (k1 + k2)


@dataclass(frozen=True)
class Heun(FixedStep):
    r"""Heun's method (explicit trapezoid), second order: $k_1 = f(t, x)$, $k_2 = f(t + h, x + h k_1)$,
    $x^+ = x + \tfrac h2 (k_1 + k_2)$. Stable on the negative real axis up to $h|\lambda| = 2$."""

    order: ClassVar[int] = 2
    middle: ClassVar[float] = 0.5
    coefficients: ClassVar[tuple[float, ...]] = (1.0,)
    stability: ClassVar[float | None] = 2.0

    def sweep(self, physics, x, stages):
        states = [x.t()]
        for times, inputs, (step,) in stages:
            for j in range(self.substeps):
                (t_a, _, t_c), (u_a, _, u_c) = times[2 * j: 2 * j + 3], inputs[2 * j: 2 * j + 3]
                x = _heun_step(physics, t_a, t_c, x, u_a, u_c, step)
            states.append(x.t())
        return torch.stack(states, dim=1)


@dataclass(frozen=True)
class SequentialHeun(Solver):
    """Heun's method at ``steps`` steps per sample interval, one sample after another (first-order hold)."""

    steps: int = 4

    def states(self, physics, t, u, x0, *, warm=None, hold="foh"):
        x, states = x0, [x0]
        for k in range(len(t) - 1):
            h = (t[k + 1] - t[k]) / self.steps
            for j in range(self.steps):
                a, c = j / self.steps, (j + 1) / self.steps
                u_a, u_c = u[:, k] + a * (u[:, k + 1] - u[:, k]), u[:, k] + c * (u[:, k + 1] - u[:, k])
                t_a = (t[k] + a * (t[k + 1] - t[k])).expand(len(x))
                x = _heun_step(physics, t_a, t_a + h, x, u_a, u_c, h)
            states.append(x)
        return torch.stack(states, dim=1)

    def integrate(self, physics, t, u, x0, *, warm=None, hold="foh", knots=None, blowup=1e8):
        return physics.output(self.states(physics, t, u, x0), u)


def _records(n: int = 601) -> list[Record]:
    truth = Oscillator(**TRUTH) + CubicStiffness(k3=K3)
    t = torch.arange(n, dtype=torch.float64) * 0.05
    records = []
    for seed in (0, 1):
        generator = torch.Generator().manual_seed(seed)
        u = torch.randn(1, n, 1, generator=generator, dtype=torch.float64).cumsum(dim=1) * 0.3
        u = u - u.mean()
        with torch.no_grad():
            y = simulate(truth, t, u, solver=Auto(rtol=1e-8))[0]
        noise = NOISE * float(y.std()) * torch.randn(y.shape, generator=generator, dtype=torch.float64)
        records.append(Record(t, u[0], y + noise, f"seed{seed}"))
    return records


@pytest.fixture(scope="module")
def records():
    return _records()


def test_the_new_solver_simulates_forward_to_its_tolerance(records):
    model = Oscillator(**TRUTH) + CubicStiffness(k3=K3)
    record = records[0]
    t, u = record.elapsed, record.u[None]
    with torch.no_grad():
        heun = simulate(model, t, u, solver=Heun(rtol=1e-4))
        fixed = simulate(model, t, u, solver=Heun(substeps=1))
        sequential = simulate(model, t, u, solver=SequentialHeun(steps=1))
    with torch.no_grad():
        exact = simulate(model, t, u, solver=Auto(rtol=1e-9))[0]
    error = float((heun[0] - exact).norm() / exact.norm())
    assert error < 1e-4
    assert float((fixed - sequential).abs().max()) < 1e-9  # the engine's sweep is the sequential method
    assert float((fixed[0] - exact).norm() / exact.norm()) > 10 * error  # second order: one step is coarse


def test_the_new_solver_fits_the_physics_by_its_own_jacobian(records):
    model = Oscillator(zeta=0.3, omega0=1.8, gain=1.2, learn=("zeta", "omega0", "gain")) + CubicStiffness(k3=0.5)
    model.set_learnable("cubic_stiffness.k3")
    fit = fit_physics(model, records, solver=Heun())
    assert type(fit.solver) is Heun and fit.solver.substeps >= 2  # the step check refined one substep
    expected = {**TRUTH, "cubic_stiffness.k3": K3}
    for name, value in expected.items():
        assert fit.parameters[name] == pytest.approx(value, rel=2e-3), name


@pytest.mark.slow  # about 8 s: the slow lane (make test-all), to keep make test under 3 minutes
def test_a_plain_solver_fits_by_central_differences_of_its_states(records):
    short = records[0].window(0, 101)
    model = Oscillator(zeta=0.3, omega0=1.8, gain=1.2, learn=("zeta", "omega0", "gain")) + CubicStiffness(k3=K3)
    fit = fit_physics(model, short, solver=SequentialHeun(steps=2), max_nfev=20)
    assert fit.solver == SequentialHeun(steps=2)  # no step to refine: the fit keeps it
    for name in ("zeta", "omega0", "gain"):
        assert fit.parameters[name] == pytest.approx(TRUTH[name], rel=1e-2), name


def test_the_ranking_refits_with_the_new_solver(records):
    train, validation = [records[0]], [records[1]]
    linear = Oscillator(zeta=0.3, omega0=1.8, gain=1.2, learn=("zeta", "omega0", "gain"))
    ranking = rank_missing_effects(linear, [CubicStiffness(), ConstantForce()], train, validation, shortlist=1,
                                   solver=Heun(), refit_budget=100)  # second order: more substeps than RK4's
    best = ranking.entries[0]
    assert best.effect == "cubic_stiffness"
    assert type(best.refit.solver) is Heun
    assert best.refit.parameters["cubic_stiffness.k3"] == pytest.approx(K3, rel=1e-2)
