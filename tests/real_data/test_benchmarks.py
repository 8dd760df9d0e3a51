"""The measured benchmarks (../shared/data): the official splits and metrics, on the linear physics.

Skipped cleanly when ``../shared/data`` is absent. The whole experiments (ladder, test metrics,
report) run as ``python experiments/{silverbox,cascaded_tanks}/run.py --out DIR``; these tests pin the
pieces that every number there rests on: loading, the split, the initial-state rule, the metric. The
discoveries on the linear physics (``--discover``'s step, about a minute each) run in the experiments lane
(``make test-experiments``).
"""

import pytest
import torch

from experiment_modules import load
from test_leaderboard import check_contract
from torchpaml import Discoverer, Estimate, Record, diagnose, fit_physics, simulate_record
from torchpaml.leaderboard import noise_floor
from torchpaml.report import discovery_to_dict

silverbox = load("silverbox/run.py")
cascaded = load("cascaded_tanks/run.py")
pytestmark = pytest.mark.skipif(not (silverbox.DATA / "train_multisine.csv").is_file()
                                or not (cascaded.DATA / "estimation.csv").is_file(),
                                reason="the measured data (../shared/data) is absent")


def test_silverbox_linear_oscillator_on_the_official_split():
    train, validation = silverbox.BENCHMARK.split(Record.from_csv(silverbox.DATA / "train_multisine.csv"))
    assert len(train.t) + len(validation.t) == 65062  # the official training record, validation inside it
    physics = silverbox.frequency_response_start(train)
    assert 2 * 3.1416 * 60 < physics.physical_parameters()["omega0"] < 2 * 3.1416 * 80  # resonance near 69 Hz
    fit = fit_physics(physics, train)
    tests = {"test_multisine": Record.from_csv(silverbox.DATA / "test_multisine.csv", "test_multisine")}
    rmse = {"test_multisine": silverbox.BENCHMARK.score(physics, tests["test_multisine"], solver=fit.solver)}
    # measured 8.81 mV; the linear reference is 8.8 mV
    assert 8.0 < rmse["test_multisine"] < 9.5
    assert 0.10 < silverbox.nrmse(rmse, tests)["test_multisine"] < 0.20


def test_cascaded_tanks_linear_physics_from_the_estimated_shared_initial_state():
    tanks = load("cascaded_tanks/tanks.py")
    estimation = Record.from_csv(cascaded.DATA / "estimation.csv", hold=cascaded.BENCHMARK.hold)
    test = Record.from_csv(cascaded.DATA / "test.csv", hold=cascaded.BENCHMARK.hold)
    physics = tanks.TwoTanks(0.01, 0.01, 0.01, 0.02, learn=("k1", "k3", "k4"))
    fit = fit_physics(physics, estimation, initial_state=Estimate())
    x0 = fit.initial_states[0]
    assert 4.0 < float(x0[1]) < 6.5  # the lower level starts near the first measured sample (5.2 V)
    error = (test.y - simulate_record(physics, test, x0, solver=fit.solver)[0])[:, 0]
    assert 0.9 < float(error.square().mean().sqrt()) < 1.4  # measured 1.16 V on the 75 % split, linear


@pytest.mark.experiment
def test_silverbox_discovery_writes_the_cubic_spring_in_closed_form():
    """Discovery alone on the linear physics (``run.py --discover``'s step) holds x**3 and reaches 1.0 mV on
    test_multisine."""
    train, validation = silverbox.BENCHMARK.split(Record.from_csv(silverbox.DATA / "train_multisine.csv"))
    found = diagnose(silverbox.frequency_response_start(train), [], train, validation, discovery=Discoverer(),
                     prober=None).discovery
    content = discovery_to_dict(found)
    terms = {t["term"]: t for t in content["terms"]}
    assert "x**3" in terms and terms["x**3"]["coefficient"] < 0, content["expression"]  # a hardening spring
    assert all(0 < t["std"] < abs(t["coefficient"]) for t in content["terms"]), content["terms"]
    test = Record.from_csv(silverbox.DATA / "test_multisine.csv", "test_multisine")
    rmse = silverbox.BENCHMARK.score(found.discovered.model, test, solver=found.discovered.solver)
    assert rmse <= 1.0, rmse  # measured 0.88 mV; the linear physics 8.81 mV


def tanks_discovery(threads: int) -> tuple[dict, float]:
    """Discovery alone on the linear tanks (``run.py --discover``'s step) on ``threads`` threads: discovery.json's
    content and the test RMSE."""
    tanks = load("cascaded_tanks/tanks.py")
    estimation = Record.from_csv(cascaded.DATA / "estimation.csv", hold=cascaded.BENCHMARK.hold)
    test = Record.from_csv(cascaded.DATA / "test.csv", hold=cascaded.BENCHMARK.hold)
    train, validation = cascaded.BENCHMARK.split(estimation)
    physics = tanks.TwoTanks(0.01, 0.01, 0.01, 0.02, learn=("k1", "k3", "k4"))
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        found = diagnose(physics, [], train, validation, initial_state=Estimate(), discovery=Discoverer(),
                         prober=None).discovery
    finally:
        torch.set_num_threads(before)
    model = found.discovered
    error = (test.y - simulate_record(model.model, test, model.train_states[0])[0])[:, 0]
    return discovery_to_dict(found), float(error.square().mean().sqrt())


@pytest.mark.experiment
def test_cascaded_tanks_discovery_finds_what_the_linear_tanks_miss_the_same_on_one_and_two_threads():
    """The linear fit sits at a double pole that the records do not determine, so the search goes by refits, one
    term at a time. Measured: a constant on the lower tank and upper**3 on the upper, 0.632 V on test (the linear
    physics 1.156 V); the same closed form and figures to 4 significant digits on one thread and on two."""
    one, rmse_one = tanks_discovery(1)
    assert one["recommended"] and one["terms"], one
    assert all(0 < t["std"] < abs(t["coefficient"]) for t in one["terms"]), one["terms"]
    assert rmse_one <= 0.8, one
    two, rmse_two = tanks_discovery(2)
    assert two["expression"] == one["expression"]
    assert [t["term"] for t in two["terms"]] == [t["term"] for t in one["terms"]]
    assert [t["coefficient"] for t in two["terms"]] == pytest.approx([t["coefficient"] for t in one["terms"]],
                                                                      rel=5e-5)
    assert rmse_two == pytest.approx(rmse_one, rel=5e-5)
    assert two["nrmse_validation"]["discovered"] == pytest.approx(one["nrmse_validation"]["discovered"], rel=5e-5)


@pytest.mark.experiment
def test_silverbox_run_writes_the_leaderboard_contract(tmp_path):
    result = silverbox.main(["--out", str(tmp_path)])
    check_contract(result, "silverbox", list(silverbox.BENCHMARK.tests))
    assert result["found"] == ["cubic_stiffness", "constant_force", "feedthrough", "quadratic_stiffness",
                               "quadratic_damping"]
    assert result["models"][-1]["rmse"]["test_multisine"] <= 0.33  # measured 0.310 mV; the goal 0.33 mV
    assert result["protocol"]["init_window"] == 50
    evidence = result["goal"]["limit"]["evidence"]  # the error stands at 1.05x the noise floor: the rule's label
    assert 1 < evidence["final_over_noise_floor"] <= 1.2 and result["goal"]["limit"]["kind"] == "noise floor"


@pytest.mark.experiment
def test_cascaded_tanks_run_writes_the_leaderboard_contract(tmp_path):
    result = cascaded.main(["--out", str(tmp_path)])
    check_contract(result, "cascaded_tanks", ["test"])
    assert result["models"][-1]["rmse"]["test"] <= 0.33  # measured 0.295 V; the goal 0.20 V is not met
    # the beam finds the pair the greedy ladder misses: greedy takes lower_overflow before upper_overflow and ends at
    # 7.25 % on validation (0.462 V on test); the runner-up's path adds both, 3.96 % (0.295 V)
    assert result["found"] == ["sqrt_outflow_lower", "upper_overflow", "sqrt_outflow_upper", "lower_overflow"]
    beam = [row for row in result["tried"] if row["stage"] == "beam"]
    (greedy,) = [row for row in beam if row["validation_gain"] == 0.0]
    (kept,) = [row for row in beam if row["kept"]]
    assert "upper_overflow" not in greedy["hypothesis"] and kept["validation_gain"] > 0.3
    assert kept["rmse"]["test"] < greedy["rmse"]["test"]
    free = result["free_spill"]  # the spill left free goes instant and does not lower the figure: 0.299 V
    assert free["rate"] > 100 * cascaded.MAX_SPILL_RATE and free["rmse"]["test"] > 0.9 * result["models"][-1]["rmse"]["test"]
    tried = [row for row in result["tried"] if row["stage"] == "hypothesis"]  # figures, or why the fit failed
    assert [row["hypothesis"].split()[0] for row in tried] == ["sensor_offset"]
    assert not any(row["kept"] for row in tried)
    (whole,) = [row for row in result["tried"] if row["stage"] == "protocol"]  # the whole record: measured 0.310 V
    assert whole["validation_gain"] is None and whole["rmse"]["test"] > 0


def test_silverbox_noise_floor_from_the_repeated_periods_of_the_training_record():
    train, _ = silverbox.BENCHMARK.split(Record.from_csv(silverbox.DATA / "train_multisine.csv"))
    floor, samples = noise_floor(train, silverbox.PERIOD)
    assert samples > 500  # the settled halves of the input's repeats at lag 8192
    assert 0.2e-3 < floor < 0.4e-3  # V; measured 0.295 mV: the grey box (0.397 mV) at 1.3x it
