"""The leaderboard (``make leaderboard``): EMPS on its protocol, and the contract every benchmark's JSON keeps.

Skipped cleanly when ../shared/data is absent. Each whole experiment runs in the experiments lane
(`make test-experiments`): EMPS about 3 minutes.
"""

import json
import math

import pytest

from experiment_modules import load
from torchpaml import leaderboard

emps = load("emps/run.py")
pytestmark = pytest.mark.skipif(not (emps.DATA / "estimation.csv").is_file(),
                                reason="the EMPS data (../shared/data/emps) are absent")


def rule_label(evidence: dict) -> str:
    """The limit the registry's rule gives these numbers, re-derived from the JSON alone: at the floor where the
    error is within 1.2 times the floor read on repeats (else where the diagnosis calls the model complete); an input
    response left where the input-driven residual removes at least 5 % of the error."""
    floor = evidence.get("noise_floor")
    at_floor = evidence["final"] <= 1.2 * floor if floor is not None else evidence["complete"]
    responds = evidence.get("with_input_residual", math.inf) <= 0.95 * evidence["final"]
    return "model class" if not at_floor else "undetermined" if responds else "noise floor"


def check_contract(result: dict, benchmark: str, splits: list[str]) -> None:
    """The leaderboard's fields (:mod:`torchpaml.leaderboard`), finite figures, and the ladder from the linear
    physics to the final grey box."""
    assert result["schema_version"] == leaderboard.SCHEMA_VERSION and result["benchmark"] == benchmark
    assert set(result["protocol"]) == {"train", "test", "init_window", "metric", "unit"}
    assert result["protocol"]["test"] == splits
    assert len(result["models"]) == 1 + len(result["found"])
    for model in result["models"]:
        assert {"model", "equation", "parameters", "uncertainty", "rmse"} <= set(model)
        assert set(splits) <= set(model["rmse"]) and all(math.isfinite(v) for v in model["rmse"].values())
    hybrid = result["hybrid"]
    assert set(hybrid) == {"model", "accepted", "rmse", "reason"} and isinstance(hybrid["accepted"], bool)
    assert set(hybrid["rmse"]) == set(splits)
    assert all(v is None or math.isfinite(v) for v in hybrid["rmse"].values())
    goal = result["goal"]
    assert set(goal) == {"value", "split", "figure", "met", "limit"} and goal["split"] in splits
    counted = hybrid if hybrid["accepted"] and hybrid["rmse"][goal["split"]] is not None else result["models"][-1]
    assert goal["figure"] == counted["rmse"][goal["split"]] and goal["met"] == (goal["figure"] <= goal["value"])
    assert goal["limit"]["kind"] in leaderboard.LIMITS and goal["limit"]["explanation"]
    assert goal["limit"]["evidence"] and all(math.isfinite(v) for v in goal["limit"]["evidence"].values())
    assert goal["limit"]["kind"] == rule_label(goal["limit"]["evidence"])
    tried = result["tried"]  # every hypothesis fitted, the ladder's refits then the probes, each scored on test
    assert all(set(row) == {"stage", "place", "hypothesis", "validation_gain", "rmse", "kept", "named"} for row in tried)
    # the rungs' kept refits are the final model's effects; of the beam's ends, the chosen one at most is kept: its
    # effects joined by " + ", the same as found
    assert [row["hypothesis"] for row in tried if row["kept"] and row["stage"].startswith("rung")] == result["found"]
    beam = [row["hypothesis"] for row in tried if row["kept"] and row["stage"] == "beam"]
    assert beam in ([], [" + ".join(result["found"])])
    assert all(row["rmse"] is not None or row["validation_gain"] is None for row in tried)  # no gain without a fit
    # a gain for every fit, but the protocol's refits on the whole training record, which hold no validation out
    assert all(row["validation_gain"] is not None or row["rmse"] is None or row["stage"] == "protocol" for row in tried)
    assert sum(row["named"] for row in tried) <= 1 and not any(row["kept"] for row in tried if row["stage"] == "probe")
    assert "Infinity" not in json.dumps(result) and "NaN" not in json.dumps(result)


@pytest.mark.experiment
def test_emps_the_rigid_body_gains_its_offset_and_coulomb_friction(tmp_path):
    result = emps.main(["--out", str(tmp_path)])
    check_contract(result, "emps", ["test"])
    assert result["found"] == ["constant_force", "coulomb_friction"]
    linear, final = (m["rmse"]["test"] for m in (result["models"][0], result["models"][-1]))
    assert linear > 50.0  # the linear rigid body drifts: measured 96.5 mm
    assert final <= 7.0  # measured 6.01 mm; CT-SUBNET 4.61 mm; the goal 4.6 mm is not met
    velocity = result["models"][-1]["rmse"]["test_velocity"]  # mm/s, against the position's central differences
    assert 0 < velocity < result["models"][0]["rmse"]["test_velocity"]
    evidence = result["goal"]["limit"]["evidence"]  # the drift is there without the test's pulses: 4.1, 4.8 mm
    assert evidence["train"] > final / 3 and evidence["validation"] > final / 3
    assert evidence["hypotheses"] >= 3 and -1 <= evidence["rank_correlation"] <= 1  # measured +0.33 over 12
    whole = [row for row in result["tried"] if row["stage"] == "protocol"]  # refitted on the whole record: 9.0 mm
    assert len(whole) == 1 and whole[0]["rmse"]["test"] > 0 and not whole[0]["kept"]
    friction = result["friction"]  # N against each direction of motion: measured 18.1 and 24.7 N
    assert 10 < friction["forward_N"] < friction["backward_N"] < 35
    final_parameters = result["models"][-1]["parameters"]
    assert 80 < final_parameters["M"] < 110 and 150 < final_parameters["Fv"] < 250  # kg, N s/m: the README's orders
    assert 15 < final_parameters["M"] * final_parameters["coulomb_friction.Fc"] < 30  # Fc in N
    assert result["seconds"] < 600
    assert json.loads((tmp_path / "emps.json").read_text()) == json.loads(json.dumps(result))
