"""A model's prediction: the start its policy gives, the output band against its analytic form, inputs-only files."""

import math

import pytest
import torch

from torchpaml import (RK4, ConfigurationError, DataError, Estimate, FittedModel, Oscillator, Record, Rest, predict,
                       pseudorandom, simulate, time_grid)
from torchpaml._fit.uncertainty import Uncertainty

X0 = torch.tensor([0.4, -0.3], dtype=torch.float64)


def _record(x0=None) -> Record:
    t = time_grid(15.0, 0.05)
    u = pseudorandom(t, 1.0, seed=2)
    with torch.no_grad():
        y = simulate(Oscillator(zeta=0.2, omega0=2.0, gain=3.0), t, u, None if x0 is None else x0[None])
    return Record(t, u[0], y[0], name="device")


def _model(policy=Rest(), std=None) -> FittedModel:
    uncertainty = None if std is None else Uncertainty(
        std, {k: (0.0, 1.0) for k in std}, torch.eye(len(std), dtype=torch.float64), 1.0, None)
    return FittedModel(Oscillator(zeta=0.2, omega0=2.0, gain=3.0), RK4(substeps=4), initial_state=policy,
                       uncertainty=uncertainty)


def test_the_band_of_the_gain_is_its_analytic_form():
    """The output is linear in the gain: dy/dgain = y / gain, so the band is y +- z std |y| / gain (z = 1.96 at 95 %).
    The Jacobian is the solver's (central differences of RK4 at 4 substeps), whose error scales with the output's
    size, not with each sample's: within 1e-6 of the band's largest half-width at every sample (near the output's
    zero crossings a bound relative to the sample itself depends on the machine's rounding)."""
    record = _record()
    prediction = predict(_model(std={"gain": 0.15}), record, level=0.95)
    half = 1.959963984540054 * 0.15 * prediction.y.abs() / 3.0
    tolerance = 1e-6 * float(half.max())
    assert float((prediction.upper - prediction.y - half).abs().max()) <= tolerance
    assert float((prediction.y - prediction.lower - half).abs().max()) <= tolerance
    assert prediction.level == 0.95


def test_a_band_of_two_parameters_adds_their_variances():
    record = _record()
    alone = [predict(_model(std={name: 0.02}), record, 0.95) for name in ("zeta", "gain")]
    both = predict(_model(std={"zeta": 0.02, "gain": 0.02}), record, 0.95)
    half = lambda p: p.upper - p.y  # noqa: E731
    assert torch.allclose(half(both), torch.sqrt(half(alone[0]) ** 2 + half(alone[1]) ** 2), rtol=1e-9, atol=1e-15)


def test_a_band_is_refused_without_uncertainty_or_with_an_undetermined_parameter():
    with pytest.raises(ConfigurationError, match="carries no parameter uncertainty"):
        predict(_model(), _record(), 0.95)
    with pytest.raises(ConfigurationError, match=r"did not determine \['zeta'\]"):
        predict(_model(std={"zeta": math.inf}), _record(), 0.95)
    with pytest.raises(ConfigurationError, match="between 0 and 1"):
        predict(_model(std={"zeta": 0.1}), _record(), 95)


@pytest.mark.parametrize("policy", [Rest(), Estimate()])
def test_the_start_follows_the_policy(policy):
    record = _record(X0)
    prediction = predict(_model(policy), record)
    expected = torch.zeros(2, dtype=torch.float64) if policy == Rest() else X0
    assert torch.allclose(prediction.x0, expected, atol=1e-6)
    assert prediction.states.shape == (len(record.t), 2) and prediction.lower is None


def test_a_file_of_inputs_alone_predicts_from_rest_and_refuses_an_estimated_start(tmp_path):
    path = tmp_path / "inputs.csv"
    path.write_text("t,u\n0,0\n0.1,1\n0.2,0.5\n0.3,0\n")
    record = Record.from_csv(path, with_outputs=False)
    assert record.metadata["outputs_missing"] and record.y.shape == (4, 1)
    assert predict(_model(), record).y.shape == (4, 1)
    with pytest.raises(DataError, match="has no output columns"):
        predict(_model(Estimate()), record)
    with pytest.raises(DataError, match="missing column"):
        Record.from_csv(path)


def test_a_record_with_other_channels_is_refused():
    model = FittedModel(Oscillator(), RK4(), inputs=("force",), outputs=("x",))
    with pytest.raises(DataError, match=r"names its inputs \['u'\]; the model was fitted on \['force'\]"):
        predict(model, _record())


def test_a_users_physics_with_two_outputs_predicts_with_a_band_per_output():
    """tests/two_mass.py (a user's physics, outputs x1 and x2), its friction's uncertainty only: the band is zero
    where the second mass rests and widens where it slides."""
    from two_mass import TwoMass
    from torchpaml import CoulombFriction

    physics = TwoMass() + CoulombFriction(0.4).on("v2")
    uncertainty = Uncertainty({"coulomb_friction_v2.Fc": 0.05}, {"coulomb_friction_v2.Fc": (0.3, 0.5)},
                              torch.eye(1, dtype=torch.float64), 1.0, None)
    model = FittedModel(physics, RK4(substeps=2), inputs=("u",), outputs=("x1", "x2"), uncertainty=uncertainty)
    t = time_grid(10.0, 0.05)
    record = Record(t, pseudorandom(t, 1.0, seed=1)[0], torch.zeros(len(t), 2), metadata={"outputs": ["x1", "x2"]})
    prediction = predict(model, record, level=0.9)
    half = prediction.upper - prediction.y
    assert prediction.y.shape == half.shape == (len(t), 2) and prediction.states.shape == (len(t), 4)
    assert float(half[0].abs().max()) == 0.0 and float(half[:, 1].max()) > 0.0 and torch.isfinite(half).all()
