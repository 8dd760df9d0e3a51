"""Export: the closed form against the physics, the pasted Python, the ONNX step in onnxruntime and the FMU in FMPy
against torchpaml's simulation, on a user's physics with two outputs, an effect with memory and linear physics
simulated exactly; and each refusal in one line."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy
import torch

from torchpaml import (RK4, TRBDF2, ChebyshevHammerstein, ConfigurationError, CoulombFriction, Exact, FittedModel,
                       Oscillator, Pendulum, Record, export_model, pseudorandom, time_grid)
from torchpaml._export.closed_form import closed_form
from torchpaml._physics.memory_effects import Hysteresis
from two_mass import TwoMass

TESTS = Path(__file__).resolve().parents[1]
#: Relative RMS within which every export reproduces torchpaml's simulation (the issue's goal: 1e-6).
TOLERANCE = 1e-6


def _models() -> dict[str, FittedModel]:
    return {
        "user physics, two outputs": FittedModel(TwoMass() + CoulombFriction(0.4).on("v2"), RK4(substeps=2),
                                                 inputs=("force",), outputs=("x1", "x2"), step=0.05),
        "effect with memory": FittedModel(Oscillator(zeta=0.1, omega0=2.0) + Hysteresis(0.5, 0.5, 0.1),
                                          RK4(substeps=1), step=0.05),
        "linear, exact": FittedModel(Oscillator(zeta=0.1, omega0=2.0, gain=3.0), Exact(), step=0.05),
    }


MODELS = _models()


def _record(model: FittedModel) -> Record:
    t = time_grid(30.0, 0.05)
    u = pseudorandom(t, 1.0, seed=4)[0]
    return Record(t, u, torch.zeros(len(t), model.physics.output_dim), metadata={
        "inputs": list(model.inputs or ["u"]), "outputs": list(model.outputs or ["y"])})


def _relative(y: np.ndarray, reference: torch.Tensor) -> float:
    return float(np.linalg.norm(y - reference.numpy()) / np.linalg.norm(reference.numpy()))


def test_the_closed_form_is_the_physics():
    """The rates and the output, evaluated as sympy expressions, equal the torch physics at random states: 1e-12."""
    generator = torch.Generator().manual_seed(0)
    for physics in (TwoMass() + CoulombFriction(0.4).on("v2"), Pendulum() + CoulombFriction(0.2),
                    Oscillator() + Hysteresis(0.5, 0.5, 0.1)):
        form = closed_form(physics)
        rates = sympy.lambdify([form.time, form.states, form.inputs], list(form.rates), "math")
        output = sympy.lambdify([form.states, form.inputs], list(form.output), "math")
        for _ in range(5):
            x = torch.randn(1, physics.state_dim, generator=generator, dtype=torch.float64)
            u = torch.randn(1, physics.input_dim, generator=generator, dtype=torch.float64)
            with torch.no_grad():
                f, h = physics.derivative(torch.zeros(1, dtype=torch.float64), x, u), physics.output(x, u)
            assert np.allclose(rates(0.0, x[0].tolist(), u[0].tolist()), f[0].numpy(), rtol=1e-12, atol=1e-14)
            assert np.allclose(output(x[0].tolist(), u[0].tolist()), h[0].numpy(), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("name", list(MODELS))
def test_the_pasted_python_simulates_the_model(name, tmp_path):
    model = MODELS[name]
    (path,) = export_model(model, code=tmp_path / "model.py")
    namespace: dict = {}
    exec(compile(path.read_text(), str(path), "exec"), namespace)  # the user's paste
    record = _record(model)
    y = np.array(namespace["simulate"](record.t.tolist(), record.u.tolist()))
    assert _relative(y, model.simulate(record)) < TOLERANCE


def test_the_c_and_latex_texts_name_the_states(tmp_path):
    model = MODELS["user physics, two outputs"]
    c, tex = export_model(model, code=tmp_path / "model.c")[0], export_model(model, code=tmp_path / "model.tex")[0]
    assert "static void step(" in c.read_text() and "const double v2 = state_[3];" in c.read_text()
    assert r"\dot{v_{2}}" in tex.read_text() and "tanh" in tex.read_text()


@pytest.mark.parametrize("name", list(MODELS))
def test_the_onnx_step_in_onnxruntime_simulates_the_model(name, tmp_path):
    onnxruntime = pytest.importorskip("onnxruntime", reason="the ONNX export is checked by onnxruntime ([export])")
    model = MODELS[name]
    (path,) = export_model(model, onnx=tmp_path / "model.onnx")
    session = onnxruntime.InferenceSession(str(path))
    record = _record(model)
    t, u = record.t.numpy(), record.u.numpy()
    x, y = np.zeros(model.physics.state_dim), []
    for k in range(len(t)):
        following = min(k + 1, len(t) - 1)
        x, out = session.run(None, {"t": t[k:k + 1], "x": x, "u0": u[k], "u1": u[following],
                                    "h": np.array([t[following] - t[k] if following > k else 0.0])})
        y.append(out)
    assert _relative(np.array(y), model.simulate(record)) < TOLERANCE


@pytest.mark.parametrize("name", list(MODELS))
def test_the_fmu_runs_in_fmpy_without_torchpaml(name, tmp_path):
    pytest.importorskip("fmpy", reason="the FMU is checked by FMPy ([export])")
    model = MODELS[name]
    (path,) = export_model(model, fmu=tmp_path / "model.fmu")
    record = _record(model)
    np.savez(tmp_path / "record.npz", t=record.t.numpy(), u=record.u.numpy())
    script = ("import sys, numpy as np; from fmu_driver import run_fmu; r = np.load('record.npz'); "
              "np.save('y.npy', run_fmu('model.fmu', r['t'], r['u'])); "
              "assert not any(m.startswith('torchpaml') for m in sys.modules), 'torchpaml was imported'")
    subprocess.run([sys.executable, "-c", script], cwd=tmp_path, check=True, env={**os.environ, "PYTHONPATH": str(TESTS)})
    assert _relative(np.load(tmp_path / "y.npy"), model.simulate(record)) < TOLERANCE


@pytest.mark.parametrize("name", list(MODELS))
def test_the_model_exchange_fmu_runs_as_the_model_in_fmpys_simulate_fmu(name, tmp_path):
    """The call a user makes: FMPy's ``simulate_fmu`` with an input table at the records' samples (no torchpaml in the
    process). The model-exchange FMU reproduces the model to 1e-6 (at each sample time the row after the event, the
    state's step; ``record_events=False`` gives those rows alone); the co-simulation FMU, whose input FMPy holds over
    each step, does not, on a model with a first-order hold."""
    pytest.importorskip("fmpy", reason="the FMU is checked by FMPy ([export])")
    model = MODELS[name]
    export_model(model, fmu=tmp_path / "cs.fmu", fmu_me=tmp_path / "me.fmu")
    record = _record(model)
    names = [s.name for s in closed_form(model.physics, model.inputs, model.outputs).inputs]
    outputs = list(model.outputs) or ["y"]
    np.savez(tmp_path / "record.npz", t=record.t.numpy(), u=record.u.numpy())
    script = (f"import sys, numpy as np; from fmpy import simulate_fmu; r = np.load('record.npz'); "
              f"table = np.array(list(zip(r['t'], *r['u'].T)), dtype=[('time', float)] + [(n, float) for n in {names!r}]); "
              f"run = lambda path, **o: simulate_fmu(path, input=table, stop_time=float(r['t'][-1]), output={outputs!r}, "
              f"output_interval=float(r['t'][1] - r['t'][0]), **o); "
              f"me = run('me.fmu'); last = np.r_[me['time'][1:] != me['time'][:-1], True]; "
              f"np.save('me.npy', np.stack([me[n][last] for n in {outputs!r}], 1)); "
              f"quiet = run('me.fmu', record_events=False); np.save('quiet.npy', np.stack([quiet[n] for n in {outputs!r}], 1)); "
              f"cs = run('cs.fmu'); np.save('cs.npy', np.stack([cs[n] for n in {outputs!r}], 1)); "
              "assert not any(m.startswith('torchpaml') for m in sys.modules), 'torchpaml was imported'")
    subprocess.run([sys.executable, "-c", script], cwd=tmp_path, check=True)
    expected = model.simulate(record)
    assert _relative(np.load(tmp_path / "me.npy"), expected) < TOLERANCE
    assert _relative(np.load(tmp_path / "quiet.npy"), expected) < TOLERANCE
    assert _relative(np.load(tmp_path / "cs.npy"), expected) > 100 * TOLERANCE


def test_the_onnx_step_of_a_hybrid_carries_the_residual_filter(tmp_path):
    """A hybrid (physics + the Chebyshev-Hammerstein residual, its coefficients random): the ONNX step, the residual's
    filter states after the physics' in x, reproduces torchpaml's hybrid output to 1e-6 (the residual's filter is
    discretised exactly at the records' interval)."""
    onnxruntime = pytest.importorskip("onnxruntime", reason="the ONNX export is checked by onnxruntime ([export])")
    residual = ChebyshevHammerstein.for_sampling(1.0, 0.05)
    with torch.no_grad():
        for parameter in (residual.numerator, residual.direct):
            parameter.copy_(torch.randn(parameter.shape, generator=torch.Generator().manual_seed(3), dtype=torch.float64))
    model = FittedModel(Oscillator(zeta=0.2) + Hysteresis(0.5, 0.5, 0.1), RK4(substeps=1), residual, step=0.05)
    (path,) = export_model(model, onnx=tmp_path / "hybrid.onnx")
    session = onnxruntime.InferenceSession(str(path))
    t = time_grid(30.0, 0.05)
    record = Record(t, 0.9 * pseudorandom(t, 1.0, seed=4)[0], torch.zeros(len(t), 1))
    x, y, T, U = np.zeros(session.get_inputs()[1].shape[0]), [], record.t.numpy(), record.u.numpy()
    for k in range(len(T)):
        after = min(k + 1, len(T) - 1)
        x, out = session.run(None, {"t": T[k:k + 1], "x": x, "u0": U[k], "u1": U[after], "h": np.array([0.05])})
        y.append(out)
    assert len(x) == 3 + residual.n * residual.order and _relative(np.array(y), model.simulate(record)) < TOLERANCE


class Erf(Oscillator):
    """A user's physics with an operation the exporter does not know (erf)."""

    def derivative(self, t, x, u):
        return super().derivative(t, x, torch.special.erf(u))


@pytest.mark.parametrize("model, message", [
    (FittedModel(Erf(), RK4(substeps=1)), "does not know the operation aten.erf.default"),
    (FittedModel(Oscillator(), RK4(), ChebyshevHammerstein.for_sampling(2.0, 0.05), step=0.05),
     r"cannot export the residual of a hybrid \(hybrid.pt\) as code"),
    (FittedModel(Oscillator(), TRBDF2(substeps=1)), "simulated by the implicit TRBDF2"),
    (FittedModel(Oscillator(), Exact()), "has no fixed step to print"),
])
def test_what_cannot_be_exported_is_refused_naming_it(model, message, tmp_path):
    with pytest.raises(ConfigurationError, match=message):
        export_model(model, code=tmp_path / "model.py")
    assert not (tmp_path / "model.py").exists()


def test_an_export_must_name_a_file_and_a_known_language(tmp_path):
    with pytest.raises(ConfigurationError, match="nothing to export"):
        export_model(MODELS["linear, exact"])
    with pytest.raises(ConfigurationError, match="names no language"):
        export_model(MODELS["linear, exact"], code=tmp_path / "model.rs")
