"""The benchmark contract (``torchpaml.leaderboard``): every registered benchmark is whole, its experiment exists and
names it, its data (where ../shared is present) holds its splits, and its metric is the one RMSE."""

import copy
import math
from pathlib import Path

import pytest
import torch

from torchpaml import (ConfigurationError, CubicStiffness, Oscillator, Record, Rest, Simulated, fit_physics,
                       simulate_record)
from torchpaml import leaderboard
from torchpaml._data.simulation import record_states
from torchpaml._diagnostics.ranking.scoring import score_model
from torchpaml.leaderboard import (BENCHMARKS, Benchmark, Published, agreement_evidence, benchmark, hypothesis_entry,
                                   noise_floor, periodic_twice, validation_agreement)

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "data"


def test_the_registry_holds_the_four_measured_benchmarks_by_name():
    assert sorted(BENCHMARKS) == ["boucwen", "cascaded_tanks", "emps", "silverbox"]
    assert all(entry.name == name for name, entry in BENCHMARKS.items())
    with pytest.raises(ConfigurationError, match="unknown benchmark 'wiener'; registered: \\['boucwen'"):
        benchmark("wiener")


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
def test_each_benchmark_is_whole_and_its_experiment_runs_it(name):
    entry = BENCHMARKS[name]
    assert entry.goal > 0 and math.isfinite(entry.goal) and entry.goal_split in entry.tests
    assert entry.published and all(p.figure and p.model and p.source for p in entry.published)
    script = ROOT / entry.experiment
    assert script.is_file() and f'benchmark("{name}")' in script.read_text()
    folder = SHARED / entry.folder
    if not folder.is_dir():
        pytest.skip(f"../shared/data/{entry.folder} is absent")
    for stem in (entry.train, *entry.tests):
        assert (folder / f"{stem}.csv").is_file(), stem


def test_a_goal_split_outside_the_tests_is_refused():
    with pytest.raises(ValueError, match="must be test splits"):
        Benchmark("b", "B", "b", "train", ("test",), "RMSE", "V", "other", 1.0,
                  (Published("1 V", "m", "s", "black box"),), "experiments/b/run.py")


def _oscillator_record(name, n=400):
    t = torch.arange(n, dtype=torch.float64) * 0.05
    u = torch.sin(1.3 * t)[:, None] + 0.5 * torch.sin(3.1 * t)[:, None]
    return Record(t, u, torch.zeros(n, 1, dtype=torch.float64), name=name)


def test_the_metric_is_the_rmse_after_the_init_window_in_the_benchmarks_unit():
    model = Oscillator(zeta=0.3, omega0=2.0, gain=4.0)
    record = _oscillator_record("test")
    entry = Benchmark("b", "B", "b", "train", ("test",), "RMSE", "mV", "test", 1.0,
                      (Published("1 mV", "m", "s", "black box"),), "experiments/b/run.py", scale=1000.0,
                      init_window=50, start="rest")
    y = simulate_record(model, record)[0]
    expected = 1000 * float(y[50:, 0].square().mean().sqrt())  # the record's y is 0: the RMSE is the output's RMS
    assert entry.score(model, record) == pytest.approx(expected, rel=1e-12)


def test_a_steady_state_split_is_scored_on_its_second_period():
    record = _oscillator_record("test_multisine")
    twice = periodic_twice(record)
    assert torch.equal(twice.u[:400], twice.u[400:]) and float(twice.t[400] - twice.t[399]) == pytest.approx(0.05)
    entry = Benchmark("b", "B", "b", "train", ("test_multisine",), "RMSE", "m", "test_multisine", 1.0,
                      (Published("1 m", "m", "s", "black box"),), "experiments/b/run.py", start="rest",
                      steady_state=("test_multisine",))
    assert entry.metric_of(twice, torch.cat([torch.ones(400, 1), torch.zeros(400, 1)])) == 0.0


def test_the_noise_floor_of_a_repeated_input_is_the_noise_and_an_input_that_never_repeats_is_refused():
    torch.manual_seed(0)
    period, n = 500, 3000
    u = torch.randn(period, dtype=torch.float64).repeat(n // period)[:, None]
    noise = 0.01 * torch.randn(n, 1, dtype=torch.float64)
    record = Record(torch.arange(n, dtype=torch.float64), u, 3 * u + noise, name="repeated")
    floor, samples = noise_floor(record, period)
    assert floor == pytest.approx(0.01, rel=0.1) and samples > 1000
    with pytest.raises(ValueError, match="does not repeat at lag 500"):
        noise_floor(Record(record.t, torch.randn(n, 1, dtype=torch.float64), record.y, name="random"), period)


def test_the_velocity_is_scored_against_the_central_differences_of_the_measured_output():
    """On the model's own noiseless output, the velocity's RMSE is the central differences' error, O(h^2): 0.05 s
    steps of a response at 1.3 and 3.1 rad/s leave under 1 % of the velocity's RMS; a model 20 % off in gain is off
    by 20 % of it. A benchmark that names no velocity state refuses to score one."""
    truth, wrong = Oscillator(zeta=0.3, omega0=2.0, gain=4.0), Oscillator(zeta=0.3, omega0=2.0, gain=4.8)
    inputs = _oscillator_record("test")
    record = Record(inputs.t, inputs.u, simulate_record(truth, inputs)[0], name="test")
    entry = Benchmark("b", "B", "b", "train", ("test",), "RMSE", "m", "test", 1.0,
                      (Published("1 m", "m", "s", "black box"),), "experiments/b/run.py", start="rest",
                      init_window=20, velocity="velocity")
    speed = float(record_states(truth, record)[20:, 1].square().mean().sqrt())
    assert entry.velocity_score(truth, record) < 0.01 * speed
    assert entry.velocity_score(wrong, record) == pytest.approx(0.2 * speed, rel=0.05)
    with pytest.raises(ConfigurationError, match="scores no velocity"):
        Benchmark("b", "B", "b", "train", ("test",), "RMSE", "m", "test", 1.0, (), "x").velocity_score(truth, record)


def test_a_hypothesis_beside_the_diagnosis_is_fitted_scored_and_never_kept():
    """The cubic spring the records hold, tried on the linear oscillator: fitted on training, its validation gain
    against the linear fit's, its test figure at the noise; one that blows up is a row without figures."""
    torch.manual_seed(0)
    device = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(2.0)
    train, validation, test = (Simulated(device, kind, 1.0, [seed], 20.0, 0.05, noise=noise).experiments()[0]
                               for kind, seed, noise in (("pseudorandom", 0, 0.02), ("multisine", 1, 0.02),
                                                         ("multisine", 2, 0.0)))
    entry = Benchmark("b", "B", "b", "train", ("test",), "RMSE", "m", "test", 1.0,
                      (Published("1 m", "m", "s", "black box"),), "experiments/b/run.py", start="rest")
    linear = Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain"))
    baseline = score_model(linear, fit_physics(linear, [train]), [validation])
    row = hypothesis_entry(entry, "hypothesis", "cubic_stiffness", copy.deepcopy(linear) + CubicStiffness(),
                           [train], {"test": test}, initial_state=Rest(), baseline=baseline, validation=[validation])
    assert row["validation_gain"] > 0.5 and not row["kept"] and row["stage"] == "hypothesis"
    assert row["rmse"]["test"] < 0.1 * entry.score(linear, test)
    runaway = Oscillator(zeta=0.01, omega0=2.0, gain=4.0, learn=("gain",)) + CubicStiffness(-1e4, learn=())
    failed = hypothesis_entry(entry, "hypothesis", "runaway", runaway, [train], {"test": test},
                              initial_state=Rest())
    assert failed["rmse"] is None and failed["hypothesis"].startswith("runaway (failed: ")


def test_the_validation_agreement_compares_each_gain_with_the_test_gain_against_the_same_baseline():
    """Rung 1's candidates against the physics (10 m on test), rung 2's and the probes against the final model (2 m):
    each test gain against its own baseline, so that a first rung's large gains do not rank against a last rung's."""
    def row(stage, gain, figure, hypothesis="h"):
        return {"stage": stage, "place": "force" if stage == "probe" else None, "hypothesis": hypothesis,
                "validation_gain": gain, "rmse": {"test": figure}, "kept": False, "named": False}

    models = [{"rmse": {"test": 10.0}}, {"rmse": {"test": 2.0}}]
    agreeing = [row("rung 1", 0.8, 2.0), row("rung 1", 0.3, 7.0), row("probe", 0.1, 1.8), row("probe", -0.2, 2.5),
                row("probe", None, None)]
    agreement = validation_agreement(agreeing, models, "test")
    assert agreement["rank_correlation"] == pytest.approx(1.0) and agreement["agree"] == 4
    assert agreement["hypotheses"] == 4
    assert agreement["best_on_test"] == {"stage": "probe: force", "hypothesis": "h", "validation_gain": 0.1, "test": 1.8}
    against = validation_agreement([row("probe", 0.3, 2.2), row("probe", 0.1, 2.1), row("probe", -0.7, 1.0, "best")],
                                   models, "test")
    assert against["rank_correlation"] == pytest.approx(-1.0) and against["agree"] == 0  # none helps on both
    evidence, sentence = agreement_evidence(against, "test", "m")
    assert evidence == {"rank_correlation": pytest.approx(-1.0), "agree": 0, "hypotheses": 3, "best_on_test": 1.0,
                        "best_on_test_validation_gain": -0.7}
    assert "agree on whether one helps for 0" in sentence and "is -1.00" in sentence
    assert "best (probe: force, 1 m), gains -70.0 % on validation" in sentence
    too_few = validation_agreement(agreeing[:2], models, "test")
    assert too_few["rank_correlation"] is None and agreement_evidence(too_few, "test", "m") == ({}, "")


def test_only_takes_names_in_one_flag_or_in_several(monkeypatch):
    """``--only a --only b`` runs both, as ``--only a b`` does (a repeated flag replaced the first before)."""
    ran = []
    monkeypatch.setattr(leaderboard.subprocess, "call", lambda command: ran.append(command[1]) or 0)
    assert leaderboard.main(["--only", "boucwen", "--only", "emps"]) == 0
    assert leaderboard.main(["--only", "boucwen", "emps"]) == 0
    assert ran == ["experiments/boucwen/run.py", "experiments/emps/run.py"] * 2
