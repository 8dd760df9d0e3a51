"""Where the mismatch points: devices whose missing part is known, diagnosed with candidates that miss it.

Each case: the hidden-effect oscillator (``test_hidden_effects.py``: pseudorandom training and multisine validation
records, 30 s at 20 Hz, 2 % noise) with one part the physics lacks, diagnosed with the library's friction and bias
forces as the only candidates, so that the ladder cannot add it and the probes run. The probe table must name the
right place first, and its library effect, added, must bring the validation mismatch within 1.5x the noise floor.
The sensor lag sits behind a cubic spring (in the physics too): on the linear oscillator a sensor lag and an
actuator lag give one output (``test_signal_effects.py``).
"""

import pytest
import torch

from torchpaml import (EFFECTS, ConstantForce, CoulombFriction, CubicStiffness, DiscoveredForce, Discoverer,
                       QuadraticDamping, Simulated, default_effects, diagnose, mismatch)

from test_hidden_effects import physics, records, truth

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane

#: the device's missing part -> (the place the probes must name, its strength, its other parameters). The sensor
#: reads only the magnitude (m = 1): the fitted linear physics has almost no gain, and the probes find it from its far
#: strength on the physics alone (``AbstractEffect.far_strength``).
DEVICES = {
    "sensor_lag": ("sensor dynamics", 0.3, {}),
    "magnitude_sensor": ("output map", 1.0, {}),
    "quadratic_input": ("input map", 0.3, {}),
    "extra_mode": ("extra mode", 12.8, {"omega_m": 8.0, "zeta_m": 0.1}),
    "latent_state": ("latent state", 0.5, {"lam": 0.3}),
}


def device(name):
    strength, others = DEVICES[name][1:]
    if name != "sensor_lag":
        return truth(name, strength, others), physics(), 1.0
    system = (truth() + CubicStiffness(2.0) + EFFECTS[name]()).assign(**{f"{name}.tau": strength})
    return system, (physics() + CubicStiffness(2.0)).set_learnable("cubic_stiffness.k3"), 1.5


@pytest.mark.parametrize("name", sorted(DEVICES))
def test_the_probes_point_at_the_missing_part_and_its_effect_reaches_the_floor(name):
    torch.manual_seed(0)
    system, model, amplitude = device(name)
    train, validation, floor = records(system, amplitude)
    diagnosis = diagnose(model, [CoulombFriction(), QuadraticDamping(), ConstantForce()], train, validation)
    probes = diagnosis.probes
    table = "\n".join(f"{r.place}: {r.fitted} {r.gain} {r.note}" for r in probes.rows)
    assert probes.validation > 2 * floor, table  # the part was missing in the first place
    best = probes.best
    assert best is probes.rows[0] and best.place == DEVICES[name][0] and best.fitted == name, table
    assert best.validation < 1.5 * floor, table
    assert best.score.parameters[f"{name}.{EFFECTS[name]().strength}"] == pytest.approx(DEVICES[name][1], rel=0.1)
    assert f"Where the mismatch points: the {best.place} ({name}" in diagnosis.verdict


def test_an_output_map_outside_the_library_is_found_in_closed_form():
    """A sensor whose gain moves with the input, y = x + 0.3 x u: no library effect, so the output map's place fits
    the closed form of the output's residual, names it, and brings validation to the floor."""
    torch.manual_seed(0)
    system = truth() + DiscoveredForce(["x*u"], [0.3], equations=["output"])
    train, validation, floor = records(system, 1.0)
    probes = diagnose(physics(), [CoulombFriction(), QuadraticDamping(), ConstantForce()], train, validation).probes
    table = "\n".join(f"{r.place}: {r.fitted} {r.gain} {r.note}" for r in probes.rows)
    best = probes.best
    assert best is probes.rows[0] and best.place == "output map" and best.fitted.startswith("y + "), table
    assert best.validation < 1.5 * floor, table
    form = best.score.model.effects["output_closed_form"]
    assert form.terms == ["u*x"] and form.values()["c_u_x"] == pytest.approx(0.3, rel=0.05)


def test_a_complete_model_is_not_probed():
    """Data from the oscillator itself: its residual is noise, and the table says so instead of probing."""
    torch.manual_seed(0)
    train, validation, floor = records(truth(), 1.0)
    probes = diagnose(physics(), [ConstantForce()], train, validation).probes
    assert probes.rows == [] and "complete at this noise level" in probes.reason
    assert 0.5 < probes.in_time.growth < 2  # the noise does not drift


def test_the_report_json_and_tensorboard_carry_the_table(tmp_path):
    import json

    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from torchpaml import write_report

    torch.manual_seed(0)
    system, model, amplitude = device("latent_state")
    train, validation, _ = records(system, amplitude)
    diagnosis = diagnose(model, [ConstantForce()], train, validation)
    write_report(diagnosis, tmp_path)
    found = json.loads((tmp_path / "diagnosis.json").read_text())["where_the_mismatch_points"]
    assert found["best"] == "latent state" and found["reason"] is None
    assert [row["place"] for row in found["probes"]] == [row.place for row in diagnosis.probes.rows]
    assert len(found["probes"]) == 8 and found["probes"][0]["fitted"] == "latent_state"
    assert found["probes"][0]["gain"] == pytest.approx(1 - found["probes"][0]["nrmse_validation"] / found["nrmse_validation"])
    assert "<h2>6. Where the mismatch points</h2>" in (tmp_path / "report.html").read_text()
    events = EventAccumulator(str(tmp_path / "tensorboard")).Reload()
    assert events.Scalars("probes/gain/latent_state")[0].value == pytest.approx(found["probes"][0]["gain"], rel=1e-6)


def test_with_every_candidate_and_discovery_a_magnitude_sensor_is_named_from_the_users_start():
    """Issue 56's drives whose speed sensor reads only the magnitude, simulated: a user's linear physics, two training
    and two validation records, the library's candidates and the discovery. The ladder's stand-in (an offset) and the
    discovery's force stay far from the floor; the linear fit alone is degenerate (no damping, a gain near zero), so
    the sensor is refitted from the physics as the user started it too, and the probes name it first, its validation
    mismatch at the floor: at least three times below the physics' (measured 98.8 % -> 1.98 %, 23 s)."""
    torch.manual_seed(0)
    system = truth("magnitude_sensor", 1.0)
    train = Simulated(system, "pseudorandom", 1.0, [0, 2], 30.0, 0.05, noise=0.02).experiments()
    validation = Simulated(system, "multisine", 1.0, [1, 3], 30.0, 0.05, noise=0.02).experiments()
    clean = Simulated(system, "multisine", 1.0, [1, 3], 30.0, 0.05).experiments()
    floor = max(mismatch(v.y, c.y) for v, c in zip(validation, clean))
    diagnosis = diagnose(physics(), default_effects(), train, validation, discovery=Discoverer())
    best = diagnosis.probes.best
    assert best is diagnosis.probes.rows[0] and best.fitted == "magnitude_sensor", diagnosis.verdict
    assert best.validation <= diagnosis.ladder.steps[0].nrmse_validation / 3 and best.validation < 1.5 * floor
    assert "as started" in best.note
