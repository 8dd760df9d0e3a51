"""The gradient of a compiled simulation (torchpaml._simulate.compiled_gradient) against the shooting engine's and
against differences of the compiled states.

Tolerances:
- compiled against reverse mode through every torch stage of one segment swept from x0 itself
  (second_order.one_segment, on the engine: no compiler): both are the derivative of the same discrete map, the
  C's and the tensors' arithmetic differ in order: held to 1e-9 relative;
- compiled against central differences of its own states (step 1e-6 in the raw parameter): truncation ~1e-12,
  rounding ~1e-10: held to 1e-6 relative;
- the values with a gradient recorded and without: the same C, held to equality.
"""

import pytest
import torch
from torch.autograd import forward_ad

from torchpaml import (RK4, TRBDF2, CoulombFriction, CubicStiffness, Hysteresis, InputLag,
                       Oscillator, simulate)
from torchpaml._simulate import compiled, compiled_gradient
from torchpaml._simulate.second_order import one_segment
from torchpaml._simulate.shooting import _Layout
from torchpaml._symbolic.compiler import compiler

pytestmark = pytest.mark.skipif(compiler() is None, reason="the compiled gradient needs a C compiler (cc, gcc) on PATH")

SAMPLES = 400


def _drive(samples: int = SAMPLES):
    generator = torch.Generator().manual_seed(0)
    t = torch.arange(samples, dtype=torch.float64) * 0.2
    return t, 0.1 * torch.randn(2, samples, 1, generator=generator, dtype=torch.float64)


def _hard():
    return Oscillator(zeta=0.1, omega0=1.0, gain=1.0, learn=("zeta", "omega0")) + CubicStiffness(200.0)


CASES = {
    "hardening spring, RK4": (_hard, RK4(substeps=2)),
    "smoothed friction, RK4": (lambda: Oscillator(zeta=0.2, omega0=1.0) + CoulombFriction(0.02), RK4(substeps=2)),
    "hysteresis, RK4": (lambda: Oscillator(zeta=0.2, omega0=1.0) + Hysteresis(), RK4(substeps=2)),
    "input lag, TR-BDF2": (lambda: Oscillator(zeta=0.2, omega0=1.0) + InputLag(0.004), TRBDF2(substeps=1)),
}


def _weighted(y):
    return (y * torch.randn(y.shape, generator=torch.Generator().manual_seed(1), dtype=torch.float64)).sum()


def _loss(physics, t, u, x0, solver):
    return _weighted(simulate(physics, t, u, x0, solver=solver))


def _gradients(physics, t, u, solver, exact=False):
    """The gradients of the loss in x0 and the parameters: by ``simulate``, or (``exact``) by reverse mode through
    every stage of one segment swept from x0."""
    physics.zero_grad()
    x0 = torch.cat([torch.tensor([[0.05, 0.0], [0.0, -0.1]], dtype=torch.float64),
                    physics.initial_state(2)[:, 2:]], dim=1).requires_grad_()
    if exact:
        states = one_segment(physics, _Layout(t, u, solver, len(t)), x0)
        _weighted(physics.output(states, u)).backward()
    else:
        _loss(physics, t, u, x0, solver).backward()
    return torch.cat([x0.grad.reshape(-1), *[p.grad.reshape(-1) for p in physics.parameters() if p.grad is not None]])


def _engine_only(monkeypatch):
    monkeypatch.setattr(compiled, "compiler", lambda: None)
    monkeypatch.setattr(compiled, "_FORMS", compiled.OrderedDict())
    monkeypatch.setattr(compiled, "_WARNED", {"no C compiler (cc, gcc) is on PATH; install one"})


def _relative(a, b):
    return float((a - b).abs().max() / b.abs().max())


@pytest.mark.parametrize("case", CASES)
def test_the_compiled_gradient_is_the_engines(case, monkeypatch):
    build, solver = CASES[case]
    physics, (t, u) = build(), _drive()
    calls = []
    original = compiled_gradient._Sensitive.apply
    monkeypatch.setattr(compiled_gradient._Sensitive, "apply", lambda *a: calls.append(1) or original(*a))
    fast = _gradients(physics, t, u, solver)
    assert calls, "the compiled gradient was not used"
    with monkeypatch.context() as patch:
        _engine_only(patch)
        reference = _gradients(physics, t, u, solver, exact=True)
    assert len(calls) == 1
    assert _relative(fast, reference) < 1e-9


def test_the_compiled_gradient_is_the_derivative_of_the_compiled_states():
    physics, (t, u) = _hard(), _drive()
    solver = RK4(substeps=2)
    x0 = torch.zeros(2, 2, dtype=torch.float64)
    parameters = [p for p in physics.parameters() if p.requires_grad]
    _loss(physics, t, u, x0, solver).backward()
    step = 1e-6
    for p in parameters:
        with torch.no_grad():
            p.add_(step)
            up = _loss(physics, t, u, x0, solver)
            p.sub_(2 * step)
            down = _loss(physics, t, u, x0, solver)
            p.add_(step)
        assert float(p.grad) == pytest.approx(float((up - down) / (2 * step)), rel=1e-6)


def test_a_gradient_does_not_change_the_values():
    physics, (t, u) = _hard(), _drive()
    recorded = simulate(physics, t, u, solver=RK4(substeps=2))
    assert recorded.requires_grad
    with torch.no_grad():
        assert torch.equal(recorded.detach(), simulate(physics, t, u, solver=RK4(substeps=2)))


@pytest.mark.parametrize("grad_mode", [True, False])
def test_forward_mode_agrees_with_reverse_mode(grad_mode):
    """A forward tangent on x0 is carried in any grad mode (forward mode does not need it)."""
    physics, (t, u) = _hard(), _drive()
    solver = RK4(substeps=2)
    x0 = torch.zeros(2, 2, dtype=torch.float64)
    direction = torch.tensor([[0.3, -0.2], [0.1, 0.4]], dtype=torch.float64)
    cotangent = torch.randn(2, len(t), 1, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    with forward_ad.dual_level(), torch.set_grad_enabled(grad_mode):
        y = simulate(physics, t, u, forward_ad.make_dual(x0, direction), solver=solver)
        tangent = forward_ad.unpack_dual(y).tangent
    start = x0.clone().requires_grad_()
    (reverse,) = torch.autograd.grad((simulate(physics, t, u, start, solver=solver) * cotangent).sum(), start)
    assert float((tangent * cotangent).sum()) == pytest.approx(float((reverse * direction).sum()), rel=1e-10)


@pytest.mark.parametrize("path", ["compiled", "engine"])
def test_a_second_derivative_is_the_derivative_of_the_gradient(path, monkeypatch):
    """create_graph=True (a Hessian-vector product) differentiates the gradient exactly on either path (the fast
    paths' own second derivatives hold their sensitivities constant: -1.376 came out as 0.0124 before), against
    central differences of the gradient (step 1e-5: truncation ~1e-10), held to 1e-6 relative."""
    if path == "engine":
        _engine_only(monkeypatch)
    physics, (t, u) = _hard(), _drive()
    solver = RK4(substeps=2)
    x0 = torch.zeros(2, 2, dtype=torch.float64)
    zeta = physics.base.parametrizations.zeta.original

    def gradient(create_graph=False):
        return torch.autograd.grad(_loss(physics, t, u, x0, solver), zeta, create_graph=create_graph)[0]

    first = gradient(create_graph=True)
    (second,) = torch.autograd.grad(first, zeta)
    step = 1e-5
    with torch.no_grad():
        zeta.add_(step)
    up = gradient()
    with torch.no_grad():
        zeta.sub_(2 * step)
    down = gradient()
    with torch.no_grad():
        zeta.add_(step)
    assert float(first) == pytest.approx(float(gradient()), rel=1e-9 if path == "compiled" else 1e-6)  # Newton's
    assert float(second) == pytest.approx(float((up - down) / (2 * step)), rel=1e-6)


@pytest.mark.parametrize("case", ["input", "tensor attribute", "too many columns"])
def test_what_the_compiled_gradient_cannot_carry_is_left_to_the_engine(case, monkeypatch):
    physics, (t, u) = _hard(), _drive()
    if case == "input":
        u = u.clone().requires_grad_()
    elif case == "tensor attribute":
        physics.effects.cubic_stiffness.scale = torch.tensor(1.0, dtype=torch.float64, requires_grad=True)
    else:
        monkeypatch.setattr(compiled_gradient, "MAX_COLUMNS", 2)
    monkeypatch.setattr(compiled_gradient._Sensitive, "apply", lambda *a: pytest.fail("the compiled gradient ran"))
    y = simulate(physics, t, u, solver=RK4(substeps=2))
    y.square().sum().backward()
    assert physics.base.parametrizations.zeta.original.grad is not None
    if case == "input":
        assert u.grad is not None and bool(u.grad.abs().sum() > 0)

