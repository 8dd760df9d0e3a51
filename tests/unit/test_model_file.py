"""The model file: a fitted model saved and loaded bit for bit (a user's physics with two outputs, an effect with
memory, a residual), in a fresh process too, and every refusal in one line."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from torchpaml import (RK4, ChebyshevHammerstein, ConfigurationError, CoulombFriction, DiscoveredForce, Estimate,
                       FittedModel, Oscillator, Record, Rest, load_model, pseudorandom, save_model, time_grid)
from torchpaml._fit.uncertainty import Uncertainty
from torchpaml._physics.memory_effects import Hysteresis
from two_mass import TwoMass

TESTS = Path(__file__).resolve().parents[1]


def _two_mass() -> FittedModel:
    """A user's physics (tests/two_mass.py) with two outputs and a friction placed on mass 2 (an attribute set after
    construction), one parameter bounded and one fixed."""
    physics = TwoMass(b=2.1, kg=4.2) + CoulombFriction(0.37).on("v2")
    physics.bound("c", 0.01, 2.0).set_learnable("d1", learn=False)
    physics.assign(c=0.4123456789012345)
    return FittedModel(physics, RK4(substeps=2), None, ("force",), ("x1", "x2"), "zoh", Estimate())


def _hysteresis() -> FittedModel:
    """An effect with memory (its own state) and the Chebyshev residual on top."""
    physics = Oscillator(zeta=0.15, omega0=1.7, gain=2.0) + Hysteresis(k=0.8, gamma=0.6, delta=0.2)
    residual = ChebyshevHammerstein.for_sampling(2.0, 0.05)
    with torch.no_grad():
        for p in residual.parameters():
            p.copy_(torch.randn(p.shape, generator=torch.Generator().manual_seed(3), dtype=p.dtype))
    return FittedModel(physics, RK4(substeps=1), residual)


def _discovered() -> FittedModel:
    """A discovered closed form (a DiscoveredForce, its coefficients parameters) on the library oscillator."""
    force = DiscoveredForce(terms=["v**3", "sign(v)"], coefficients=[-0.5, -0.2])
    return FittedModel(Oscillator(zeta=0.15) + force, RK4(substeps=1), step=0.05)


def _record(inputs: int = 1, outputs: int = 1) -> Record:
    t = time_grid(10.0, 0.05)
    u = torch.cat([pseudorandom(t, 1.0, seed=i) for i in range(inputs)], dim=-1)[0]
    return Record(t, u, torch.zeros(len(t), outputs))


@pytest.mark.parametrize("build", [_two_mass, _hysteresis, _discovered])
def test_a_saved_model_loads_bit_for_bit(build, tmp_path):
    model = build()
    loaded = load_model(save_model(model, tmp_path / "model.pt"), trust=("two_mass",))
    saved, read = model.physics.state_dict(), loaded.physics.state_dict()
    assert list(saved) == list(read) and all(torch.equal(saved[k], read[k]) for k in saved)
    assert loaded.physics.physical_parameters() == model.physics.physical_parameters()
    assert loaded.physics.learnable_names() == model.physics.learnable_names()
    assert loaded.physics.effect_names() == model.physics.effect_names()
    assert (loaded.solver, loaded.inputs, loaded.outputs, loaded.hold, loaded.initial_state) == (
        model.solver, model.inputs, model.outputs, model.hold, model.initial_state)
    record = _record(outputs=model.physics.output_dim)
    assert torch.equal(loaded.simulate(record), model.simulate(record))


def test_a_model_loads_in_a_fresh_process_and_simulates_bit_for_bit(tmp_path):
    model = _hysteresis()
    save_model(model, tmp_path / "model.pt")
    record = _record()
    torch.save({"t": record.t, "u": record.u}, tmp_path / "record.pt")
    script = ("import torch, torchpaml as tp; torch.set_num_threads(1); r = torch.load('record.pt'); "
              "m = tp.load_model('model.pt'); "
              "torch.save(m.simulate(tp.Record(r['t'], r['u'], torch.zeros(len(r['t']), 1))), 'y.pt')")
    env = {**os.environ, "PYTHONPATH": str(TESTS), "OMP_NUM_THREADS": "1"}
    subprocess.run([sys.executable, "-c", script], cwd=tmp_path, env=env, check=True)
    torch.set_num_threads(1)
    assert torch.equal(torch.load(tmp_path / "y.pt"), model.simulate(record))


def _rewritten(path: Path, change) -> Path:
    """The file at ``path`` with ``change`` applied to its content and its digest kept (a tampered file)."""
    stored = torch.load(path, weights_only=True)
    change(stored["content"])
    torch.save(stored, path)
    return path


def test_a_changed_file_is_refused(tmp_path):
    path = save_model(_two_mass(), tmp_path / "model.pt")
    _rewritten(path, lambda content: content["physics"]["state"].__setitem__(
        next(iter(content["physics"]["state"])), torch.tensor(9.0, dtype=torch.float64)))
    with pytest.raises(ConfigurationError, match="was changed after it was written"):
        load_model(path)


def test_a_file_from_a_newer_version_or_with_a_missing_class_is_refused(tmp_path, monkeypatch):
    from torchpaml._model import file

    monkeypatch.setattr(file, "library_version", lambda: "99.0.0")
    newer = save_model(_hysteresis(), tmp_path / "newer.pt")
    monkeypatch.undo()
    with pytest.raises(ConfigurationError, match=r"written by torchpaml 99\.0\.0.*upgrade torchpaml"):
        load_model(newer)
    missing = _two_mass()
    missing.physics.base._built_with = (type("Gone", (TwoMass,), {"__module__": "nowhere"}),
                                        *missing.physics.base._built_with[1:])
    path = save_model(missing, tmp_path / "missing.pt")
    with pytest.raises(ConfigurationError, match=r"names class nowhere\.Gone, which cannot be imported"):
        load_model(path, trust=("nowhere",))


def test_a_file_with_code_or_not_a_model_is_refused(tmp_path):
    torch.save(torch.nn.Linear(2, 1), tmp_path / "module.pt")  # a pickled module: loading it would run code
    with pytest.raises(ConfigurationError, match="not a torchpaml model file"):
        load_model(tmp_path / "module.pt")
    torch.save({"weights": torch.zeros(3)}, tmp_path / "weights.pt")
    with pytest.raises(ConfigurationError, match="not a torchpaml model file"):
        load_model(tmp_path / "weights.pt")
    with pytest.raises(ConfigurationError, match="no model file at"):
        load_model(tmp_path / "absent.pt")


class Tabulated(Oscillator):
    """A user's physics built with an argument a model file cannot keep (a function)."""

    def __init__(self, law=abs):
        super().__init__()
        self.law = law


def test_a_model_a_file_cannot_keep_is_refused_naming_the_argument(tmp_path):
    with pytest.raises(ConfigurationError, match=r"cannot save Tabulated: its argument 'law' is a builtin_function"):
        save_model(FittedModel(Tabulated(law=abs), RK4()), tmp_path / "model.pt")


def test_the_uncertainty_travels_with_the_model(tmp_path):
    uncertainty = Uncertainty({"gain": 0.1, "zeta": 0.01}, {"gain": (1.8, 2.2), "zeta": (0.13, 0.17)},
                              torch.tensor([[1.0, 0.3], [0.3, 1.0]], dtype=torch.float64), 1.2, None)
    model = FittedModel(Oscillator(zeta=0.15, omega0=1.7, gain=2.0), RK4(), initial_state=Rest(),
                        uncertainty=uncertainty)
    loaded = load_model(save_model(model, tmp_path / "model.pt")).uncertainty
    assert loaded.std == uncertainty.std and loaded.interval == uncertainty.interval
    assert torch.equal(loaded.correlation, uncertainty.correlation) and loaded.collinearity == 1.2
