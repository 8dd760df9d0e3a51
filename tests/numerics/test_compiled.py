"""The compiled RK4 (torchpaml._simulate.compiled) against the shooting engine's RK4 on the same records.

Tolerances:
- both take the same stages, hold and step coefficients; the rates are printed from the closed form, whose
  arithmetic order differs from the tensors', so they agree to rounding (measured 5e-15 relative), held to 1e-12
  against the engine's sequential result (one segment: no Newton);
- gradients through the shooting engine started from the compiled states against reverse mode through every RK4
  stage of one segment: the engine's sensitivities are central differences of the starts (error ~1e-10 each,
  accumulated over the record's memory), held to 1e-6 relative, as in test_rk4.
"""

import pytest
import torch

from torchpaml import (RK4, AbstractPhysics, CoulombFriction, CubicStiffness, Hysteresis, InputLag, Oscillator,
                       PhysicalParameter, Positive, SimulationError, register_parameters, simulate, state_vector)
from torchpaml._simulate import compiled
from torchpaml._symbolic.compiler import compiler

pytestmark = pytest.mark.skipif(compiler() is None, reason="the compiled RK4 needs a C compiler (cc, gcc) on PATH")

SAMPLES = compiled.MIN_STEPS // 2 + 1  # two rows at one substep: just enough steps to compile


def _drive(samples: int = SAMPLES, jitter: bool = False):
    generator = torch.Generator().manual_seed(0)
    steps = torch.full((samples,), 0.2, dtype=torch.float64)
    if jitter:
        steps = steps * (1 + 0.3 * torch.rand(samples, generator=generator, dtype=torch.float64))
    t = torch.cumsum(steps, 0) - steps[0]
    return t, 0.1 * torch.randn(2, samples, 1, generator=generator, dtype=torch.float64)


def _hard():
    return Oscillator(zeta=0.1, omega0=1.0, gain=1.0, learn=("zeta", "omega0")) + CubicStiffness(200.0)


def _form(physics):
    """The compiled form kept for ``physics``' current structure."""
    return compiled._FORMS[compiled._signature(physics)]


def _relative(a, b):
    return float((a - b).abs().max() / b.abs().max())


class Power(AbstractPhysics):
    """$\\dot x = v$, $\\dot v = b u - c v - k x |x|^{p-1}$: a spring whose law is a plain attribute ``power``."""

    state_names = ("x", "v")

    def __init__(self, power: int = 3):
        super().__init__()
        self.power = power
        register_parameters(self, [PhysicalParameter("k", 1.0, "1/s^2", Positive(), "spring"),
                                   PhysicalParameter("c", 0.3, "1/s", Positive(), "damping")], ("k", "c"))

    def derivative(self, t, x, u):
        position, velocity = x.unbind(-1)
        spring = self.k * position * position.abs() ** (self.power - 1)
        return state_vector([velocity, u[..., 0] - self.c * velocity - spring])

    def output(self, x, u):
        return x[..., :1]


@pytest.mark.parametrize("physics", [_hard(), Oscillator(zeta=0.2, omega0=1.0) + Hysteresis(),
                                     Oscillator(zeta=0.2, omega0=1.0) + CoulombFriction(0.02),
                                     Oscillator(zeta=0.2, omega0=1.0) + InputLag(0.5)],
                         ids=["cubic", "hysteresis", "friction", "input lag"])
@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_the_compiled_rk4_is_the_engines_rk4(physics, hold):
    t, u = _drive(jitter=hold == "zoh")
    x0 = torch.tensor([[0.05, 0.0], [0.0, -0.1]], dtype=torch.float64)
    x0 = torch.cat([x0, physics.initial_state(2)[:, 2:]], dim=1)
    with torch.no_grad():
        states = compiled.sequential_states(physics, t, u, x0, RK4(substeps=2), hold)
        sequential = simulate(physics, t[:400], u[:, :400], x0, solver=RK4(substeps=2, segment=400), hold=hold)
    assert states is not None
    assert _relative(physics.output(states[:, :400], u[:, :400]), sequential) < 1e-12


def test_new_parameters_need_no_new_compile_and_a_new_structure_gets_one():
    physics = Power(3)
    t, u = _drive()
    x0 = physics.initial_state(2)
    with torch.no_grad():
        first = compiled.sequential_states(physics, t, u, x0, RK4(substeps=1), "foh")
        form = _form(physics)
        physics.parametrizations.k.original.add_(0.5)
        stiffer = compiled.sequential_states(physics, t, u, x0, RK4(substeps=1), "foh")
        assert _form(physics) is form
        physics.power = 5
        quintic = compiled.sequential_states(physics, t, u, x0, RK4(substeps=1), "foh")
        assert _form(physics) is not form
        reference = simulate(physics, t[:300], u[:, :300], x0, solver=RK4(substeps=1, segment=300))
    assert _relative(first, stiffer) > 1e-3
    assert _relative(physics.output(quintic[:, :300], u[:, :300]), reference) < 1e-12


class Spring(Power):
    """:class:`Power` whose spring law is a function it was given: an attribute that is neither plain nor a tensor."""

    def __init__(self, law):
        super().__init__()
        self.law = law

    def derivative(self, t, x, u):
        position, velocity = x.unbind(-1)
        return state_vector([velocity, u[..., 0] - self.c * velocity - self.k * self.law(position)])


def test_two_physics_that_differ_only_in_a_function_they_hold_get_two_forms():
    """A user's effect that keeps its law as a function (a lambda) compiles once per function: the same class with
    another function is another structure, never the first one's stale form."""
    t, u = _drive()
    cubic, odd = Spring(lambda x: x**3), Spring(lambda x: x * x.abs())
    x0 = cubic.initial_state(2)
    with torch.no_grad():
        for physics in (cubic, odd):
            states = compiled.sequential_states(physics, t, u, x0, RK4(substeps=1), "foh")
            reference = simulate(physics, t[:300], u[:, :300], x0, solver=RK4(substeps=1, segment=300))
            assert _relative(physics.output(states[:, :300], u[:, :300]), reference) < 1e-12
    assert _form(cubic) is not _form(odd)


def test_the_gradient_through_the_compiled_start_is_exact(monkeypatch):
    """An input that requires a gradient leaves the graph to the shooting engine (the compiled gradient carries the
    parameters and the initial state), whose Newton starts from the compiled states."""
    monkeypatch.setattr(compiled, "MIN_STEPS", 1000)
    physics = _hard()
    t, u = _drive(1000)
    u.requires_grad_()

    def gradient(segment):
        physics.zero_grad()
        u.grad = None
        simulate(physics, t, u, solver=RK4(substeps=2, segment=segment)).square().sum().backward()
        return torch.cat([u.grad.reshape(-1), *[p.grad.reshape(-1) for p in physics.parameters() if p.grad is not None]])

    shooting = gradient(2)
    assert _form(physics) is not None
    assert _relative(shooting, gradient(10**6)) < 1e-6  # one segment: reverse mode through every RK4 stage


def test_a_blow_up_is_still_reported_where_it_happens():
    physics = Oscillator(zeta=0.1, omega0=1.0, learn=()) + CubicStiffness(-200.0)  # softening: escapes past x = 0.07
    t, u = _drive()
    u = 5 * u
    with pytest.raises(SimulationError, match="blew up"):
        simulate(physics, t, u, solver=RK4(substeps=1))


@pytest.mark.parametrize("case", ["short record", "no compiler", "not RK4"])
def test_what_is_not_compiled_is_left_to_the_engine(case, monkeypatch):
    from torchpaml import TRBDF2

    t, u = _drive(SAMPLES if case != "short record" else 100)
    solver = TRBDF2(substeps=1) if case == "not RK4" else RK4(substeps=1)
    monkeypatch.setattr(compiled, "_FORMS", compiled.OrderedDict())
    if case == "no compiler":
        monkeypatch.setattr(compiled, "compiler", lambda: None)
        monkeypatch.setattr(compiled, "_WARNED", {"no C compiler (cc, gcc) is on PATH; install one"})
    physics = _hard()
    with torch.no_grad():
        assert compiled.sequential_states(physics, t, u, physics.initial_state(2), solver, "foh") is None


@pytest.mark.slow  # 15 to 35 s: the slow lane (make test-all)
def test_forward_mode_and_functional_call_leave_the_module_compiled(monkeypatch):
    monkeypatch.setattr(compiled, "MIN_STEPS", 1000)
    physics = _hard()
    t, u = _drive(1000)
    key = "base.parametrizations.zeta.original"
    raw = physics.base.parametrizations.zeta.original.detach().clone()

    def output(r):
        return torch.func.functional_call(physics, {key: r}, (t, u[:1]), {"solver": RK4(substeps=2)})

    _, tangent = torch.func.jvp(output, (raw,), (torch.ones_like(raw),))
    cotangent = torch.randn(u[:1].shape, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    (reverse,) = torch.autograd.grad((output(raw.requires_grad_()) * cotangent).sum(), raw)
    assert float((tangent * cotangent).sum()) == pytest.approx(float(reverse), rel=1e-9)
    with torch.no_grad():
        assert compiled.sequential_states(physics, t, u, physics.initial_state(2), RK4(substeps=1), "foh") is not None
