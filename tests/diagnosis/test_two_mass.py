"""A device with two sensors: a user's two-mass chain (force on mass 1, both positions measured) whose second mass
has Coulomb friction the physics lacks.

The ranking must try each force on each degree of freedom and find the friction on ``v2``; the diagnosis must say
that it shows most at output 2 and bring both outputs to their noise floor (the mismatch of the noise-free record,
computed here); the same from two training records of unequal length given to ``torchpaml diagnose``.
"""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import torch

from two_mass import FRICTION, TRUTH, TwoMass
from torchpaml import (
    ConstantForce,
    CoulombFriction,
    CubicStiffness,
    Discoverer,
    Simulated,
    channel_mismatch,
    diagnose,
    write_report,
)
from torchpaml.analysis import hybrid_residual
from torchpaml.report import diagnosis_to_dict

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane

NOISE = 0.02


def device():
    return TwoMass(**TRUTH) + CoulombFriction(FRICTION, 0.01).on("v2")


def record(signal, seed, duration=40.0, noise=NOISE):
    return Simulated(device(), signal, 1.0, [seed], duration, 0.02, noise=noise).experiments()[0]


@pytest.fixture(scope="module")
def diagnosis():
    return diagnose(TwoMass(), [CoulombFriction(), CubicStiffness(), ConstantForce()], record("pseudorandom", 0),
                    record("multisine", 1))


def test_the_ranking_finds_the_friction_on_the_second_mass(diagnosis):
    assert diagnosis.ladder.added == ["coulomb_friction_v2"]
    names = [e.effect for e in diagnosis.ranking.entries]  # every force on each degree of freedom
    assert {"coulomb_friction_v1", "coulomb_friction_v2", "cubic_stiffness_v1", "cubic_stiffness_v2"} <= set(names)
    assert diagnosis.ladder.final.parameters["coulomb_friction_v2.Fc"] == pytest.approx(FRICTION, rel=0.05)


def test_it_shows_most_at_output_2_and_both_outputs_reach_the_noise_floor(diagnosis):
    floor = channel_mismatch(record("multisine", 1).y, record("multisine", 1, noise=0.0).y)  # ~2 % each
    assert diagnosis.shows_most.name == "y2"
    assert "the missing effect shows most at output y2" in diagnosis.verdict
    for channel, noise in zip(diagnosis.channels, floor, strict=True):
        assert channel.physics > 5 * float(noise)  # the physics alone fails on both: 24 % and 33 %
        assert channel.final < 1.1 * float(noise), channel.name


def test_the_residual_on_top_sees_both_outputs_and_adds_nothing_to_complete_physics(diagnosis):
    final = diagnosis.hybrids[-1]
    assert not final.adequacy.inadequate  # physics complete at this noise level
    assert final.hybrid_validation > 0.95 * final.physics_validation  # nothing to add: 2.00 % -> 2.16 %
    residual, y_physics = hybrid_residual(diagnosis.ladder.final, [record("pseudorandom", 0)], 1.05)
    assert residual.outputs == 2 and y_physics.shape[-1] == 2


def test_the_report_and_the_json_hold_each_channel(diagnosis, tmp_path):
    write_report(diagnosis, tmp_path)
    content = json.loads((tmp_path / "diagnosis.json").read_text())
    channels = content["where_it_fails"]["channels"]
    assert [c["name"] for c in channels] == ["y1", "y2"] and content["where_it_fails"]["shows_most"] == "y2"
    assert content == json.loads(json.dumps(diagnosis_to_dict(diagnosis)))
    assert "y2" in (tmp_path / "report.html").read_text()


def test_the_discovery_reads_both_outputs():
    """Without candidates, the discovery on both outputs beats the physics (it does not find the friction's form:
    the how-to says so, and the ranking above finds it)."""
    found = diagnose(TwoMass(), [], record("pseudorandom", 0), record("multisine", 1),
                     discovery=Discoverer()).discovery
    assert found.discovered is not None and found.recommended
    assert "v2" in found.expression  # the second mass's velocity carries what is missing


def test_two_training_records_of_unequal_length_from_the_command_line(tmp_path):
    for name, signal, seed, duration in (("a", "pseudorandom", 0, 24.0), ("b", "pseudorandom", 2, 16.0),
                                         ("v", "multisine", 1, 40.0)):
        written = record(signal, seed, duration)
        written.to_csv(tmp_path / f"{name}.csv")
    assert (tmp_path / "a.csv").read_text().splitlines()[1] == "t,u,y1,y2"
    (tmp_path / "config.yaml").write_text(textwrap.dedent("""
        physics:
          class_path: two_mass.TwoMass
        effects: [coulomb_friction, constant_force]
    """))
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}
    done = subprocess.run([sys.executable, "-m", "torchpaml", "diagnose", "--config", "config.yaml", "--data", "a.csv",
                           "b.csv", "--validation", "v.csv", "--out", "out", "--quiet"], capture_output=True, text=True,
                          cwd=tmp_path, env=env, timeout=600)
    assert done.returncode == 0, done.stderr
    content = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert [step["model"] for step in content["ladder"]] == ["TwoMass", "TwoMass + coulomb_friction_v2"]
    assert content["where_it_fails"]["shows_most"] == "y2"
    assert content["ladder"][-1]["nrmse_validation"] < 1.1 * NOISE


class NamedTwoMass(TwoMass):
    output_names = ("x1", "x2")


def test_the_outputs_go_by_the_physics_names_where_the_records_give_none():
    found = diagnose(NamedTwoMass(), [CoulombFriction()], record("pseudorandom", 0, 20.0), record("multisine", 1, 20.0))
    assert [c.name for c in found.channels] == ["x1", "x2"] and found.shows_most.name == "x2"
