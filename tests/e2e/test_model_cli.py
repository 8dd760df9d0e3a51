"""The model a diagnosis writes: ``model.pt`` reproduces the diagnosis' validation output bit for bit in a fresh
process, ``torchpaml simulate --model`` predicts from it, and its refusals exit 2 in one line."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from torchpaml import Record, load_model, predict
from torchpaml.cli import main

#: an end-to-end run (the slow lane), on one worker of xdist so that the diagnosis it reads runs once
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("model_cli")]

ONE_THREAD = {**os.environ, "OMP_NUM_THREADS": "1"}


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "torchpaml", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300, env=ONE_THREAD)


def refused(*args, cwd, capsys, monkeypatch) -> tuple[int, str]:
    """A command that must refuse, run in this process (a subprocess costs seconds of imports): its exit status and
    stderr."""
    monkeypatch.chdir(cwd)
    monkeypatch.setattr("sys.argv", ["torchpaml"])
    with pytest.raises(SystemExit) as stop:
        main(list(args))
    return stop.value.code, capsys.readouterr().err


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    """An oscillator with a cubic stiffness diagnosed on the library physics: the folder with model.pt."""
    folder = tmp_path_factory.mktemp("diagnosed")
    with pytest.MonkeyPatch.context() as patch:  # the records written in this process; the diagnosis on one thread
        patch.setattr("sys.argv", ["torchpaml"])
        for name, seed in (("train", 1), ("val", 2)):
            main(["simulate", "--physics", "oscillator", "--effect", "cubic_stiffness=2", "--duration", "30", "--dt",
                  "0.05", "--noise", "0.01", "--seed", str(seed), "--out", str(folder / f"{name}.csv")])
    done = run("diagnose", "--data", "train.csv", "--validation", "val.csv", "--physics", "oscillator",
               "--effect", "cubic_stiffness", "--out", "out", "--quiet", cwd=folder)
    assert done.returncode == 0, done.stderr
    return folder


def test_the_model_file_reproduces_the_validation_figure_bit_for_bit(diagnosed):
    """A fresh process (one thread) loads model.pt and scores the validation record: the diagnosis' final figure."""
    content = json.loads((diagnosed / "out" / "diagnosis.json").read_text())
    final = content["ladder"][-1]
    script = ("import torch, torchpaml as tp; torch.set_num_threads(1); m = tp.load_model('out/model.pt'); "
              "r = tp.Record.from_csv('val.csv'); y = tp.predict(m, r).y; "
              "print(repr(tp.mismatch(r.y, y)))")  # the one error measure, as the diagnosis computed it
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=diagnosed,
                          env=ONE_THREAD, timeout=300)
    assert done.returncode == 0, done.stderr
    assert float(done.stdout) == final["nrmse_validation"]
    assert "cubic_stiffness" in load_model(diagnosed / "out" / "model.pt").physics.effect_names()


def test_simulate_with_a_model_writes_outputs_states_and_band(diagnosed):
    done = run("simulate", "--model", "out/model.pt", "--data", "val.csv", "--band", "0.95", "--out", "pred.csv",
               cwd=diagnosed)
    assert done.returncode == 0, done.stderr
    lines = (diagnosed / "pred.csv").read_text().splitlines()
    metadata, header = json.loads(lines[0][2:]), lines[1].split(",")
    model, record = load_model(diagnosed / "out" / "model.pt"), Record.from_csv(diagnosed / "val.csv")
    states = [f"state_{name}" for name in model.physics.state_names]
    assert header == ["t", "u", "y", *states, "y_lower", "y_upper"] and len(states) == 2
    table = np.loadtxt(diagnosed / "pred.csv", delimiter=",", skiprows=2)
    expected = predict(model, record, 0.95)
    assert np.array_equal(table[:, 2], expected.y[:, 0].numpy()) and metadata["band_level"] == 0.95
    assert np.all(table[:, 5] <= table[:, 2]) and np.all(table[:, 2] <= table[:, 6])
    assert np.isfinite(table).all() and (table[:, 6] - table[:, 5]).max() > 0


@pytest.mark.parametrize("args, message", [
    (["--model", "out/model.pt", "--out", "p.csv"], "simulate --model needs --data"),
    (["--model", "out/absent.pt", "--data", "val.csv", "--out", "p.csv"], "no model file at out/absent.pt"),
    (["--model", "val.csv", "--data", "val.csv", "--out", "p.csv"], "is not a torchpaml model file"),
    (["--out", "p.csv"], "simulate needs --physics"),
])
def test_simulate_with_a_model_refuses_in_one_line(diagnosed, args, message, capsys, monkeypatch):
    code, err = refused("simulate", *args, cwd=diagnosed, capsys=capsys, monkeypatch=monkeypatch)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (diagnosed / "p.csv").exists()


def test_a_changed_model_file_is_refused_by_the_command(diagnosed, capsys, monkeypatch):
    stored = torch.load(diagnosed / "out" / "model.pt", weights_only=True)
    stored["content"]["hold"] = "zoh"
    torch.save(stored, diagnosed / "changed.pt")
    code, err = refused("simulate", "--model", "changed.pt", "--data", "val.csv", "--out", "p.csv", cwd=diagnosed,
                        capsys=capsys, monkeypatch=monkeypatch)
    assert code == 2 and "was changed after it was written" in err


def test_export_writes_an_fmu_an_onnx_step_and_code_that_reproduce_the_validation_record(diagnosed):
    """The diagnosis' model exported from the command line: the FMU (run by FMPy in a process without torchpaml),
    the ONNX step (onnxruntime) and the pasted Python each reproduce the model on the validation record to 1e-6."""
    pytest.importorskip("fmpy", reason="the FMU is checked by FMPy ([export])")
    onnxruntime = pytest.importorskip("onnxruntime", reason="the ONNX step is checked by onnxruntime ([export])")
    done = run("export", "--model", "out/model.pt", "--fmu", "model.fmu", "--onnx", "model.onnx", "--code", "model.py",
               cwd=diagnosed)
    assert done.returncode == 0, done.stderr
    model, record = load_model(diagnosed / "out" / "model.pt"), Record.from_csv(diagnosed / "val.csv")
    reference = model.simulate(record).numpy()
    relative = lambda y: float(np.linalg.norm(y - reference) / np.linalg.norm(reference))  # noqa: E731
    np.savez(diagnosed / "val.npz", t=record.t.numpy(), u=record.u.numpy())
    script = ("import sys, numpy as np; from fmu_driver import run_fmu; r = np.load('val.npz'); "
              "np.save('fmu_y.npy', run_fmu('model.fmu', r['t'], r['u'])); "
              "assert not any(m.startswith('torchpaml') for m in sys.modules)")
    tests = str(Path(__file__).resolve().parents[1])
    subprocess.run([sys.executable, "-c", script], cwd=diagnosed, check=True, env={**ONE_THREAD, "PYTHONPATH": tests})
    assert relative(np.load(diagnosed / "fmu_y.npy")) < 1e-6
    session, t, u = onnxruntime.InferenceSession(str(diagnosed / "model.onnx")), record.t.numpy(), record.u.numpy()
    x, y = np.zeros(model.physics.state_dim), []
    for k in range(len(t)):
        after = min(k + 1, len(t) - 1)
        x, out = session.run(None, {"t": t[k:k + 1], "x": x, "u0": u[k], "u1": u[after], "h": t[after:after + 1] - t[k]})
        y.append(out)
    assert relative(np.array(y)) < 1e-6
    namespace: dict = {}
    exec((diagnosed / "model.py").read_text(), namespace)
    assert relative(np.array(namespace["simulate"](t.tolist(), u.tolist()))) < 1e-6


@pytest.mark.parametrize("args, message", [
    (["--model", "out/model.pt"], "nothing to export"),
    (["--model", "out/model.pt", "--code", "model.rs"], "names no language"),
    (["--model", "out/absent.pt", "--code", "m.py"], "no model file at out/absent.pt"),
])
def test_export_refuses_in_one_line(diagnosed, args, message, capsys, monkeypatch):
    code, err = refused("export", *args, cwd=diagnosed, capsys=capsys, monkeypatch=monkeypatch)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_track_writes_track_json_and_flags_a_changed_device(diagnosed, monkeypatch):
    """The diagnosis' model followed along its validation record (no alarm) and along a record of a device whose
    cubic stiffness tripled (an alarm naming it); the commands run in this process (a subprocess costs seconds of
    imports; the export test runs the command line in its own)."""
    monkeypatch.chdir(diagnosed)
    monkeypatch.setattr("sys.argv", ["torchpaml"])
    main(["simulate", "--physics", "oscillator", "--effect", "cubic_stiffness=6", "--duration", "30", "--dt", "0.05",
          "--noise", "0.01", "--seed", "2", "--out", "changed.csv"])
    for data, folder in (("val.csv", "track_same"), ("changed.csv", "track_changed")):
        main(["track", "--model", "out/model.pt", "--data", data, "--out", folder, "--window", "2",
              "--attribution", "10"])  # 20 Hz: windows of 40 and 200 samples
        assert (diagnosed / folder / "track.png").stat().st_size > 0
    same = json.loads((diagnosed / "track_same" / "track.json").read_text())
    changed = json.loads((diagnosed / "track_changed" / "track.json").read_text())
    assert set(same) >= {"schema_version", "alarms", "innovation_rms", "seconds"} and same["alarms"] == []
    assert changed["alarms"] and set(changed["alarms"][0]) == {"t", "statistic", "parameter"}
    assert changed["alarms"][0]["parameter"] == "cubic_stiffness.k3"
    assert changed["innovation_rms"]["y"] > 1.5 * same["innovation_rms"]["y"]


@pytest.mark.parametrize("args, message", [
    (["--model", "out/model.pt", "--data", "val.csv", "--out", "t", "--alpha", "2"], "0 < alpha < 1"),
    (["--model", "out/model.pt", "--data", "val.csv", "--out", "t", "--noise", "0"], "needs each output's noise"),
    (["--model", "out/absent.pt", "--data", "val.csv", "--out", "t"], "no model file at out/absent.pt"),
])
def test_track_refuses_in_one_line(diagnosed, args, message, capsys, monkeypatch):
    code, err = refused("track", *args, cwd=diagnosed, capsys=capsys, monkeypatch=monkeypatch)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
