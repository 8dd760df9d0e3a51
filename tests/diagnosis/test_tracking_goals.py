"""Tracking's goals on simulated devices at 1 kHz, 12 s records: a friction that doubles at a known time (6 s) is
flagged within 2 s and named, with no false alarm on ten records without a change; the same on an effect with memory
and on a user's physics with two outputs; the same on streams that start while the device moves; and an integrating
plant (a rigid body with friction, its position measured, the model fitted to a short noisy record) tracked over two
minutes without a false alarm."""

import copy
import dataclasses

import pytest
import torch

from torchpaml import (RK4, Auto, CoulombFriction, Estimate, FittedModel, Oscillator, PhysicalParameter, Positive,
                       Record, SecondOrderPhysics, fit_physics, pseudorandom, register_parameters, time_grid, track)
from torchpaml._physics.memory_effects import Hysteresis
from two_mass import TwoMass

pytestmark = pytest.mark.slow  # 12 s records at 1 kHz: the slow lane

H, DURATION, CHANGE = 0.001, 12.0, 6.0
#: Output noise, as a share of the output's RMS.
NOISE = 0.01


def _device(physics, changed, seed: int, inputs: int = 1, moving: float = 0.0) -> Record:
    """``physics`` until CHANGE, ``changed`` after (from the state reached), measured with NOISE; with ``moving``,
    the device is driven for that many seconds before the stream starts (it starts in motion)."""
    t = time_grid(moving + DURATION, H)
    u = torch.cat([pseudorandom(t, 1.0, seed=seed + 100 * i) for i in range(inputs)], dim=-1)
    k, first = round((moving + CHANGE) / H), round(moving / H)
    solver = Auto(start=RK4(substeps=1))
    with torch.no_grad():
        before = solver.states(physics, t[: k + 1], u[:, : k + 1], physics.initial_state(1))
        after = solver.states(changed, t[k:], u[:, k:], before[:, -1])
        y = torch.cat([physics.output(before, u[:, : k + 1]), changed.output(after[:, 1:], u[:, k + 1:])], dim=1)[0]
    y, u = y[first:], u[0, first:]
    sigma = NOISE * y.square().mean(0).sqrt()
    y = y + sigma * torch.randn(y.shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
    return Record(t[first:] - t[first], u, y, metadata={"noise": sigma.tolist()})


def _model(physics, record: Record, **fields) -> FittedModel:
    return FittedModel(physics, RK4(substeps=1), step=H, noise=tuple(record.metadata["noise"]), **fields)


def _doubled(physics, name: str):
    changed = copy.deepcopy(physics)
    return changed.assign(**{name: 2 * changed.physical_parameters()[name]})


#: The oscillator's parameters a diagnosis fits (the tracker names the one that moved among those).
LEARN = ("zeta", "omega0", "gain")

CASES = {
    "friction": (Oscillator(zeta=0.1, omega0=5.0, gain=25.0, learn=LEARN) + CoulombFriction(1.0),
                 "coulomb_friction.Fc", {}),
    "effect with memory": (Oscillator(zeta=0.1, omega0=5.0, gain=25.0, learn=LEARN) + Hysteresis(20.0, 0.5, 0.1),
                           "hysteresis.k", {}),
    "user physics, two outputs": (TwoMass() + CoulombFriction(0.4).on("v2"), "coulomb_friction_v2.Fc",
                                  {"inputs": ("u",), "outputs": ("x1", "x2")}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_doubled_parameter_is_flagged_within_2_s_and_named(case):
    physics, name, fields = CASES[case]
    record = _device(physics, _doubled(physics, name), seed=0)
    tracking = track(_model(physics, record, **fields), record)
    assert tracking.alarms, f"no alarm; the statistic peaked at {tracking.statistic.max():.4g}"
    first = tracking.alarms[0]
    assert CHANGE <= first.t <= CHANGE + 2.0 and first.parameter == name, tracking.alarms


@pytest.mark.parametrize("case", list(CASES))
def test_no_false_alarm_on_ten_records_without_a_change(case):
    physics, _, fields = CASES[case]
    for seed in range(1, 11) if case == "friction" else range(1, 3):
        record = _device(physics, physics, seed)
        tracking = track(_model(physics, record, **fields), record)
        assert tracking.alarms == [], (seed, tracking.alarms, tracking.statistic.max(), tracking.threshold)


#: The pre-roll of the streams that start in motion, s: the device has been driven that long when the stream starts.
MOVING = 3.0


@pytest.mark.parametrize("case", ["friction", "user physics, two outputs"])
def test_a_stream_that_starts_in_motion_raises_no_false_alarm_and_flags_a_change_within_2_s(case):
    """The start is estimated from the stream's first window: no alarm at t = 0 on a device already moving (a filter
    started at rest alarms at once), and the doubled parameter is still flagged within 2 s and named."""
    physics, name, fields = CASES[case]
    for seed in (1, 2):
        record = _device(physics, physics, seed, moving=MOVING)
        tracking = track(_model(physics, record, **fields), record)
        assert tracking.alarms == [], (seed, tracking.alarms)
        assert abs(tracking.x0).max() > 0.05  # the device was moving: the start is not rest
    at_rest = track(_model(physics, record, **fields), record, x0=physics.initial_state(1)[0])
    assert at_rest.alarms and at_rest.alarms[0].t < 0.5  # what the estimated start prevents
    record = _device(physics, _doubled(physics, name), seed=0, moving=MOVING)
    tracking = track(_model(physics, record, **fields), record)
    assert tracking.alarms, f"no alarm; the statistic peaked at {tracking.statistic.max():.4g}"
    first = tracking.alarms[0]
    assert CHANGE <= first.t <= CHANGE + 2.0 and first.parameter == name, tracking.alarms


class RigidBody(SecondOrderPhysics):
    """An integrating plant: $\\ddot x = g u - b \\dot x$ (a rigid body driven by a force, viscous friction), position
    measured."""

    def __init__(self, g: float = 2.0, b: float = 1.0, *, learn=("g", "b")):
        super().__init__()
        register_parameters(self, [PhysicalParameter("g", g, "m/(s^2 N)", Positive(), "drive gain"),
                                   PhysicalParameter("b", b, "1/s", Positive(), "viscous friction")], learn)

    def acceleration(self, t, x, v, u):
        return self.g * u - self.b * v


def test_an_integrating_plant_fitted_to_a_short_record_is_tracked_for_two_minutes_without_a_false_alarm():
    """A rigid body with Coulomb friction, its model fitted to 4 s of noisy data (its parameters off by a few percent):
    the filter trusting it fully (no process noise) alarms on the unchanged device within 30 s, as its position drifts;
    the process noise from the fit's uncertainty keeps the window sum at its chi-squared mean and raises none in 120 s."""
    device = RigidBody() + CoulombFriction(0.5, eps=0.1)

    def measured(seed: int, seconds: float, moving: float, noise: float) -> Record:
        t = time_grid(moving + seconds, H)
        u = pseudorandom(t, 1.0, seed=seed)
        with torch.no_grad():
            y = device.output(RK4(substeps=1).states(device, t, u, device.initial_state(1)), u)[0]
        first = round(moving / H)
        y = y[first:] + noise * torch.randn(y[first:].shape, generator=torch.Generator().manual_seed(seed),
                                            dtype=torch.float64)
        return Record(t[first:] - t[first], u[0, first:], y)

    physics = RigidBody(1.8, 0.9) + CoulombFriction(0.4, eps=0.1)
    fit = fit_physics(physics, measured(0, 4.0, 0.0, 0.03), solver=RK4(substeps=1), initial_state=Estimate())
    model = dataclasses.replace(fit.model, step=H, noise=(0.01,))
    for seed in (1, 2):
        stream = measured(seed, 120.0, MOVING, 0.01)
        tracking = track(model, stream)
        assert tracking.alarms == [], (seed, tracking.alarms)
        judged = tracking.statistic[round(1.0 / H):]
        assert judged.mean() == pytest.approx(round(0.5 / H), rel=0.05)  # chi-squared with pW = 500 degrees
        trusting = track(model, stream, process=(0.0, 0.0))
        assert trusting.alarms and trusting.alarms[0].t < 30.0
