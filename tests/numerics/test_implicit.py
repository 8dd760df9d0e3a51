"""TR-BDF2, the implicit solver: its order against scipy, stiff physics integrated where RK4 is unstable, exact
gradients (reverse mode and the fit's Jacobian, against central differences), and fits that agree with RK4's where
both apply.

Tolerances: second order is held by the error ratio of halved steps (4 in theory, held to [3.5, 4.5]); the
stiff tank's TR-BDF2 output to 1e-3 of the output against scipy's Radau at rtol 1e-12; gradients to 1e-6
relative; fitted parameters of the two solvers within 0.5 standard errors of each other.
"""

import pytest
import torch

import torchpaml as tp
from torchpaml import RK4, TRBDF2, ResolutionError, simulate

from oracles import oracle


class SpillingTank(tp.AbstractPhysics):
    r"""A tank that spills above its rim: $\dot h = b\,u - k\,h - c\,\max(h - r, 0)$, output $h$. Stiff for $c\,\Delta t \gg 1$."""

    state_names = ("level",)

    def __init__(self, k=0.1, b=0.2, c=50.0, rim=1.0, *, learn=("k", "b", "c")):
        super().__init__()
        tp.register_parameters(self, [
            tp.PhysicalParameter("k", k, "1/s", tp.Positive(), "outflow rate"),
            tp.PhysicalParameter("b", b, "1/(V s)", tp.Positive(), "pump gain"),
            tp.PhysicalParameter("c", c, "1/s", tp.Positive(), "spill rate above the rim"),
            tp.PhysicalParameter("rim", rim, "m", tp.Positive(), "rim"),
        ], learn)

    def derivative(self, t, x, u):
        level = x[..., 0]
        return tp.state_vector([self.b * u[..., 0] - self.k * level - self.c * (level - self.rim).clamp(min=0)])

    def output(self, x, u):
        return x[..., :1]


@pytest.fixture(scope="module")
def pump():
    """(t, u): 120 s sampled every second, the pump's voltage a slow multisine around 0.8 V."""
    t = tp.time_grid(120.0, 1.0)
    return t, 0.8 + 0.6 * tp.multisine(t, 1.0, [0.005, 0.01, 0.02, 0.04], seed=0)


def relative_error(y, reference):
    return float((y - reference).norm() / reference.norm())


def test_trbdf2_is_second_order_on_a_smooth_nonlinear_model():
    t = torch.arange(200, dtype=torch.float64) * 0.1
    u = tp.multisine(t, 1.0, [0.1, 0.3, 0.7], seed=1)
    model = tp.Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + tp.CubicStiffness(1.5)
    reference = oracle(model, t, u)
    with torch.no_grad():
        errors = [relative_error(simulate(model, t, u, solver=TRBDF2(substeps=m)), reference) for m in (2, 4, 8)]
    assert all(3.5 < coarse / fine < 4.5 for coarse, fine in zip(errors, errors[1:]))


@pytest.mark.slow
def test_a_stiff_spill_is_integrated_at_one_step_per_sample_where_rk4_is_unstable(pump):
    t, u = pump
    tank = SpillingTank(c=500.0)  # c times the sample interval: 500
    reference = oracle(tank, t, u, method="Radau")
    assert float((reference > 1.0).double().mean()) > 0.5  # the level spends most of the record above the rim
    with torch.no_grad():
        implicit = simulate(tank, t, u, solver=TRBDF2(substeps=1))
        explicit = simulate(tank, t, u, solver=RK4(substeps=16))  # h c / 16 = 31: far outside RK4's stability
        default = simulate(tank, t, u)
    assert relative_error(implicit, reference) < 1e-3
    assert relative_error(explicit, reference) > 1e-2
    assert relative_error(default, reference) < 1e-3  # the default: RK4 cannot, so TR-BDF2
    with pytest.raises(ResolutionError, match=r"RK4 .*TRBDF2\(\)"):
        simulate(tank, t, u, solver=RK4())


def test_gradients_of_a_stiff_simulation_match_central_differences():
    """A lag 100 times faster than the sampling: reverse mode and the fit's Jacobian (central differences through
    the implicit-function correction) agree with central differences of simulations; forward mode is refused,
    naming what works."""
    t = torch.arange(120, dtype=torch.float64) * 0.05
    u = tp.multisine(t, 1.0, [0.3, 0.7, 1.1], seed=3)
    weights = torch.randn(u.shape, generator=torch.Generator().manual_seed(4), dtype=torch.float64)
    model = tp.Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=("zeta",)) + tp.InputLag(tau=0.0005)
    solver = TRBDF2(substeps=1)
    key, raw = "base.parametrizations.zeta.original", model.base.parametrizations.zeta.original.detach().clone()

    def loss(value):
        return (torch.func.functional_call(model, {key: value}, (t, u), {"solver": solver}) * weights).sum()

    leaf = raw.clone().requires_grad_()
    (reverse,) = torch.autograd.grad(loss(leaf), leaf)
    step = 1e-6
    with torch.no_grad():
        central = (loss(raw + step) - loss(raw - step)) / (2 * step)
    y, J = tp.engine.output_jacobian(model, ["zeta"], t, u, solver=solver)
    assert float(reverse) == pytest.approx(float(central), rel=1e-6)
    assert float((J[..., 0] * weights).sum()) == pytest.approx(float(central), rel=1e-6)
    with pytest.raises(NotImplementedError, match="reverse mode"):
        torch.func.jvp(loss, (raw,), (torch.ones_like(raw),))


def noisy_record(truth, t, u):
    y = oracle(truth, t, u, method="Radau")
    noise = 0.01 * float(y.std()) * torch.randn(y.shape, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    return tp.Record(t, u[0], (y + noise)[0])


@pytest.mark.slow
def test_the_implicit_fit_equals_the_resolved_rk4_fit_where_both_apply(pump):
    t, u = pump
    record = noisy_record(SpillingTank(c=5.0), t, u)  # h c = 5: RK4 resolves it at a few substeps
    explicit = tp.fit_physics(SpillingTank(k=0.2, b=0.3, c=2.5), record, solver=RK4())
    implicit = tp.fit_physics(SpillingTank(k=0.2, b=0.3, c=2.5), record, solver=TRBDF2())
    assert isinstance(explicit.solver, RK4) and isinstance(implicit.solver, TRBDF2)
    for name, value in explicit.parameters.items():
        assert abs(implicit.parameters[name] - value) < 0.5 * explicit.uncertainty.std[name], name


@pytest.mark.slow
def test_the_default_fit_integrates_a_stiff_spill_with_the_implicit_method(pump):
    t, u = pump
    record = noisy_record(SpillingTank(c=500.0), t, u)
    model = SpillingTank(k=0.2, b=0.3, c=250.0)
    fit = tp.fit_physics(model, record)
    assert isinstance(fit.solver, TRBDF2)
    assert fit.mismatch < 1.5 * 0.01 * float(record.y.std()) / float(record.y.square().mean().sqrt())
    for name, truth in {"k": 0.1, "b": 0.2}.items():
        assert abs(fit.parameters[name] - truth) < 4 * fit.uncertainty.std[name], name
    assert fit.parameters["c"] > 100  # a fast spill, told from a slow one (the data hardly resolve its rate)
    with pytest.raises(ResolutionError, match=r"stiff for RK4"):
        tp.fit_physics(SpillingTank(k=0.2, b=0.3, c=250.0), record, solver=RK4())
