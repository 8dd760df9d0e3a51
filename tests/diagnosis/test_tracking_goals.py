"""Tracking's goals on simulated devices at 1 kHz, 12 s records: a friction that doubles at a known time (6 s) is
flagged within 2 s and named, with no false alarm on ten records without a change; the same on an effect with memory and on a user's
physics with two outputs."""

import copy

import pytest
import torch

from torchpaml import RK4, Auto, CoulombFriction, FittedModel, Oscillator, Record, pseudorandom, time_grid, track
from torchpaml._physics.memory_effects import Hysteresis
from two_mass import TwoMass

pytestmark = pytest.mark.slow  # 12 s records at 1 kHz: the slow lane

H, DURATION, CHANGE = 0.001, 12.0, 6.0
#: Output noise, as a share of the output's RMS.
NOISE = 0.01


def _device(physics, changed, seed: int, inputs: int = 1) -> Record:
    """``physics`` until CHANGE, ``changed`` after (from the state reached), measured with NOISE."""
    t = time_grid(DURATION, H)
    u = torch.cat([pseudorandom(t, 1.0, seed=seed + 100 * i) for i in range(inputs)], dim=-1)
    k = round(CHANGE / H)
    solver = Auto(start=RK4(substeps=1))
    with torch.no_grad():
        before = solver.states(physics, t[: k + 1], u[:, : k + 1], physics.initial_state(1))
        after = solver.states(changed, t[k:], u[:, k:], before[:, -1])
        y = torch.cat([physics.output(before, u[:, : k + 1]), changed.output(after[:, 1:], u[:, k + 1:])], dim=1)[0]
    sigma = NOISE * y.square().mean(0).sqrt()
    y = y + sigma * torch.randn(y.shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
    return Record(t, u[0], y, metadata={"noise": sigma.tolist()})


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
