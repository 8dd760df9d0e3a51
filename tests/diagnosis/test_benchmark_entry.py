"""A new benchmark is one entry and its data: a ``Benchmark`` that names its physics (``model``) and no script is run
by the registry's own protocol (``python -m torchpaml.leaderboard --only NAME``), end to end, on records written as
the shared benchmarks' CSVs."""

import json

import pytest
import torch

from torchpaml import ConstantForce, CubicStiffness, Oscillator, Simulated
from torchpaml.leaderboard import BENCHMARKS, Benchmark, Published, main

pytestmark = pytest.mark.slow  # an end-to-end diagnosis: the slow lane


def duffing_benchmark(**fields) -> Benchmark:
    """A Duffing oscillator's benchmark, as an entry file would define it: the linear oscillator as the physics."""
    return Benchmark(
        name="duffing", title="Duffing", folder="duffing", train="train", tests=("test",), metric="RMSE, free run",
        unit="mV", scale=1000.0, start="rest", goal_split="test", goal=30.0,
        published=(Published("—", "none", "a test entry", "grey box"),),
        model=lambda train: Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain")),
        candidates=lambda: [CubicStiffness(), ConstantForce()], **fields)


@pytest.fixture
def data(tmp_path):
    """``train.csv`` (pseudorandom, 2 % noise) and ``test.csv`` (a multisine, noiseless) of the oscillator with a
    cubic spring (k3 = 2)."""
    torch.manual_seed(0)
    device = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(2.0)
    folder = tmp_path / "data" / "duffing"
    Simulated(device, "pseudorandom", 1.0, [0], 30.0, 0.05, noise=0.02).experiments()[0].to_csv(folder / "train.csv")
    Simulated(device, "multisine", 1.0, [1], 30.0, 0.05).experiments()[0].to_csv(folder / "test.csv")
    return tmp_path / "data"


def test_an_entry_with_a_model_is_run_by_the_registrys_protocol(data, tmp_path, monkeypatch):
    monkeypatch.setitem(BENCHMARKS, "duffing", duffing_benchmark())
    assert main(["--results", str(tmp_path / "results"), "--data", str(data), "--only", "duffing"]) == 0
    result = json.loads((tmp_path / "results" / "duffing" / "duffing.json").read_text())
    assert result["benchmark"] == "duffing" and result["found"] == ["cubic_stiffness"]
    linear, final = (row["rmse"]["test"] for row in (result["models"][0], result["models"][-1]))
    assert final < 0.2 * linear  # the cubic spring found removes most of the test error
    assert result["models"][-1]["parameters"]["cubic_stiffness.k3"] == pytest.approx(2.0, rel=0.05)
    goal = result["goal"]
    assert goal["figure"] == final and goal["met"] == (final <= 30.0)
    assert goal["limit"]["kind"] == "noise floor"  # the cubic spring was all the physics missed
    assert [row["hypothesis"] for row in result["tried"] if row["kept"]] == ["cubic_stiffness"]
    assert (tmp_path / "results" / "duffing" / "diagnosis" / "diagnosis.json").is_file()


def test_missing_data_and_an_entry_without_a_model_or_a_script_are_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(BENCHMARKS, "duffing", duffing_benchmark())
    assert main(["--results", str(tmp_path), "--data", str(tmp_path / "nowhere"), "--only", "duffing"]) == 2
    assert "lacks train.csv, test.csv; point --data at the Duffing data" in capsys.readouterr().err
    with pytest.raises(ValueError, match="give either an experiment script or a model"):
        duffing_benchmark(experiment="experiments/duffing/run.py")


def test_a_bad_record_is_said_with_its_fix_and_a_nonzero_exit(data, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(BENCHMARKS, "duffing", duffing_benchmark())
    path = data / "duffing" / "train.csv"
    lines = path.read_text().splitlines()
    first = 1 + lines[0].startswith("#")  # the metadata line, then the header
    lines[first + 40] = ",".join(lines[first + 40].split(",")[:-1] + ["nan"])
    path.write_text("\n".join(lines) + "\n")
    assert main(["--results", str(tmp_path / "results"), "--data", str(data), "--only", "duffing"]) == 2
    error = capsys.readouterr().err
    assert "duffing: DataError: record 'train': column 'y' has 1 NaN/inf value(s), first at row 40" in error
    assert "drop or interpolate those samples" in error
