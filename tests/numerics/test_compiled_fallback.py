"""The compiled path never breaks a simulation or a fit: where C cannot be built or loaded, the torch engine
simulates, with one CompiledPathWarning, and gives the same numbers (held to 1e-9 relative: the engine's RK4 and the
compiled RK4 agree to rounding, the engine's Jacobian is a central difference of ~1e-7).

The cases: no compiler (also for the linear recurrence), a cache folder that cannot be written (a file where the folder should be: the same refusal
for root, who may write anywhere), a library that does not load (built for another machine, or on a noexec mount), a
compile that fails, a compile that hangs, a physics the tracer cannot take (no warning: the engine is its path).
And two ways a compiled form could give stale or wrong numbers: a tensor attribute changed after a compile, and a
user's RK4 subclass with its own step.
"""

import os
import stat
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import sympy
import torch

from torchpaml import (RK4, TRBDF2, AbstractPhysics, CompiledPathWarning, CubicStiffness, Oscillator,
                       PhysicalParameter, Positive, fit_physics, register_parameters, simulate, state_vector)
from torchpaml._data import Record
from torchpaml._simulate import compiled
from torchpaml._simulate import compiled_jacobian as jacobians
from torchpaml._simulate import compiled_recurrence as recurrences
from torchpaml._simulate.scan import constant_recurrence
from torchpaml._simulate.sensitivity import raw_parameters
from torchpaml._symbolic import compiler as compilers

pytestmark = pytest.mark.skipif(compilers.compiler() is None, reason="the compiled path needs a C compiler on PATH")


@pytest.fixture(autouse=True)
def _fresh_forms(monkeypatch):
    """No form or warning kept from another test: each case compiles (or fails to) afresh."""
    monkeypatch.setattr(compiled, "_WARNED", set())
    monkeypatch.setattr(compiled, "_FORMS", compiled.OrderedDict())


def _hard():
    return Oscillator(zeta=0.1, omega0=1.0, gain=1.0, learn=("zeta", "omega0")) + CubicStiffness(200.0)


def _record(samples: int = 400) -> Record:
    generator = torch.Generator().manual_seed(0)
    t = torch.arange(samples, dtype=torch.float64) * 0.1
    u = 0.1 * torch.randn(samples, 1, generator=generator, dtype=torch.float64)
    with torch.no_grad():
        y = simulate(Oscillator(zeta=0.12, omega0=1.1, gain=1.0) + CubicStiffness(180.0), t, u[None],
                     solver=RK4(substeps=1))[0]
    compiled._FORMS.clear()  # the record's simulation compiled the structure: each case compiles (or fails to) afresh
    return Record(t, u, y)


def _engine_fit(record: Record, monkeypatch) -> dict:
    """The fit with the compiled path switched off: the engine's numbers."""
    with monkeypatch.context() as patch:
        patch.setattr(compiled, "compiler", lambda: None)
        patch.setattr(compiled, "_FORMS", compiled.OrderedDict())
        patch.setattr(compiled, "_WARNED", set())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CompiledPathWarning)
            return fit_physics(_hard(), record, solver=RK4(substeps=1)).parameters


def _assert_same_fit(fitted: dict, engine: dict) -> None:
    for name, value in engine.items():
        assert fitted[name] == pytest.approx(value, rel=1e-6), name  # the optimum, reached along two Jacobians


def _fit_warns(record: Record, match: str) -> dict:
    physics = _hard()
    with pytest.warns(CompiledPathWarning, match=match):
        fitted = fit_physics(physics, record, solver=RK4(substeps=1)).parameters
    form = compiled._FORMS[compiled._signature(physics)]
    assert form is None or form.sensitivities is False
    return fitted


def test_no_compiler_falls_back_with_one_warning(monkeypatch):
    record = _record()
    engine = _engine_fit(record, monkeypatch)
    monkeypatch.setattr(compiled, "compiler", lambda: None)
    fitted = _fit_warns(record, "no C compiler")
    _assert_same_fit(fitted, engine)
    with warnings.catch_warnings():
        warnings.simplefilter("error", CompiledPathWarning)  # one warning per reason and process
        fit_physics(_hard(), record, solver=RK4(substeps=1))


def test_a_cache_that_cannot_be_written_falls_back(monkeypatch, tmp_path):
    record = _record()
    engine = _engine_fit(record, monkeypatch)
    (tmp_path / "torchpaml").write_text("a file where the cache folder should be")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    _assert_same_fit(_fit_warns(record, "cannot be created"), engine)


@pytest.mark.slow  # 15 to 35 s: the slow lane (make test-all)
def test_a_library_that_does_not_load_falls_back(monkeypatch, tmp_path):
    record = _record()
    engine = _engine_fit(record, monkeypatch)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    built = subprocess.run([sys.executable, "-c", _BUILD], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[2])})
    library = Path(built.stdout.strip().splitlines()[-1])  # built and cached by another process: not loaded here
    library.write_bytes(b"built for another machine")  # now it is no library at all
    os.chmod(library, stat.S_IRUSR | stat.S_IWUSR)
    _assert_same_fit(_fit_warns(record, "does not load"), engine)


#: Another process compiles the structure's RK4 library into the cache and prints where.
_BUILD = """
from torchpaml import CubicStiffness, Oscillator
from torchpaml._simulate import compiled
from torchpaml._symbolic.compiler import cached_library
form = compiled._Compiled(Oscillator(zeta=0.1, omega0=1.0, gain=1.0, learn=("zeta", "omega0")) + CubicStiffness(200.0))
print(cached_library(compiled._source(form, 2, 1), "simulate", "the test"))
"""


def test_a_compile_that_fails_falls_back(monkeypatch, tmp_path):
    record = _record()
    engine = _engine_fit(record, monkeypatch)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(compilers, "compiler", lambda: "false")  # a compiler that fails on every source
    _assert_same_fit(_fit_warns(record, "did not compile"), engine)


def test_a_compile_that_hangs_is_given_up(monkeypatch, tmp_path):
    record = _record()
    engine = _engine_fit(record, monkeypatch)
    hanging = tmp_path / "cc"
    hanging.write_text("#!/bin/sh\nsleep 30\n")
    hanging.chmod(0o700)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(compilers, "compiler", lambda: str(hanging))
    monkeypatch.setattr(compilers, "COMPILE_SECONDS", 1)
    _assert_same_fit(_fit_warns(record, "ran past 1 s"), engine)


class Branching(AbstractPhysics):
    """A spring whose law is chosen by a Python branch on the state's value: the tracer cannot take it."""

    state_names = ("x", "v")

    def __init__(self):
        super().__init__()
        register_parameters(self, [PhysicalParameter("k", 1.0, "1/s^2", Positive(), "spring")], ("k",))

    def derivative(self, t, x, u):
        position, velocity = x.unbind(-1)
        stiffer = 2.0 if float(position.detach().abs().max()) > 1.0 else 1.0
        return state_vector([velocity, u[..., 0] - 0.3 * velocity - stiffer * self.k * position])

    def output(self, x, u):
        return x[..., :1]


def test_a_physics_the_tracer_cannot_take_is_the_engines_without_a_warning():
    record = _record()
    physics = Branching()
    with warnings.catch_warnings():
        warnings.simplefilter("error", CompiledPathWarning)
        fit = fit_physics(physics, record, solver=RK4(substeps=1))
    assert compiled._FORMS[compiled._signature(physics)] is None
    assert fit.parameters["k"] > 0


class Tabled(AbstractPhysics):
    """A spring whose coefficients are a plain tensor attribute (neither parameter nor buffer)."""

    state_names = ("x", "v")

    def __init__(self):
        super().__init__()
        self.table = torch.tensor([1.0, 0.3], dtype=torch.float64)
        register_parameters(self, [PhysicalParameter("b", 1.0, "1/s^2", Positive(), "gain")], ("b",))

    def derivative(self, t, x, u):
        position, velocity = x.unbind(-1)
        return state_vector([velocity, self.b * u[..., 0] - self.table[1] * velocity - self.table[0] * position])

    def output(self, x, u):
        return x[..., :1]


@pytest.mark.parametrize("solver", [RK4(substeps=1), TRBDF2(substeps=1)], ids=["RK4", "TRBDF2"])
def test_a_changed_tensor_attribute_is_compiled_again(solver):
    physics = Tabled()
    record = _record(200)
    t, u = record.elapsed, record.u[None]
    raw = raw_parameters(physics, ["b"])
    before = jacobians.compiled_jacobian(physics, raw, t, u, physics.initial_state(1), solver, "foh", False)[0]
    physics.table = torch.tensor([4.0, 0.3], dtype=torch.float64)
    after = jacobians.compiled_jacobian(physics, raw, t, u, physics.initial_state(1), solver, "foh", False)[0]
    with torch.no_grad():
        engine = simulate(physics, t, u, solver=solver.__class__(substeps=1, segment=10**6))
    assert float((before - after).abs().max()) > 1e-3
    assert float((after - engine).abs().max() / engine.abs().max()) < 1e-9


def test_a_users_rk4_with_its_own_step_is_not_replaced():
    class Damped(RK4):
        """RK4 whose step a user changed: every state shrunk by 1 % after each sweep's steps."""

        def sweep(self, physics, x, stages):
            return 0.99 * super().sweep(physics, x, stages)

    assert Damped.compiles is None and RK4.compiles == "rk4"
    physics = _hard()
    record = _record(compiled.MIN_STEPS + 1)  # long enough for the compiled RK4
    with torch.no_grad():
        own = simulate(physics, record.elapsed, record.u[None], solver=Damped(substeps=1))
        plain = simulate(physics, record.elapsed, record.u[None], solver=RK4(substeps=1))
    assert float((own - plain).abs().max()) > 1e-3 * float(plain.abs().max())


def test_a_closed_form_with_a_function_c_has_no_name_for_is_a_compile_failure_not_a_crash():
    """``re`` (what sympy writes for the derivative of ``Abs`` of an expression it cannot call real) has no C name:
    the printer's refusal becomes the compile failure that the fallback takes, naming the function."""
    import sympy

    x = sympy.Symbol("x_[0]", real=True)
    assert "fabs" in compiled.c_function("outputs", "const double *x_", {"out_[0]": sympy.Abs(x)})
    with pytest.raises(compilers.UnbuildableError, match=r"outputs: its closed form holds a function C has no name "
                                                          r"for .*: re\)"):
        compiled.c_function("outputs", "const double *x_", {"out_[0]": sympy.re(sympy.Symbol("z") * x)})


def test_the_linear_recurrence_without_a_compiler_runs_the_scan(monkeypatch, tmp_path):
    """Linear physics and the residual's filters step their states in C; without a compiler (and nothing cached) the
    scan steps them instead, with one warning, to the same states within 1e-12."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    generator = torch.Generator().manual_seed(3)
    A = torch.tensor([[0.6, 0.5], [-0.4, 0.7]], dtype=torch.float64)
    b = torch.randn(2, 500, 2, generator=generator, dtype=torch.float64)
    z0 = torch.randn(2, 2, generator=generator, dtype=torch.float64)
    stepped = recurrences.sequential_recurrence(A, b, z0)
    monkeypatch.setattr(compilers, "compiler", lambda: None)
    recurrences._library.cache_clear()
    try:
        with pytest.warns(CompiledPathWarning, match="no C compiler"):
            z = constant_recurrence(A, b, z0)
        assert recurrences.sequential_recurrence(A, b, z0) is None
    finally:
        recurrences._library.cache_clear()
    assert stepped is not None and torch.allclose(z, stepped, rtol=1e-12, atol=1e-12 * float(stepped.abs().max()))
