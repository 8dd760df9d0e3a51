"""``torchpaml simulate``: generated measurements read back, and its errors."""

import subprocess
import sys

import pytest

from torchpaml import build_model, Record, simulate
from torchpaml._signals import pseudorandom_knots

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "torchpaml", "simulate", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def test_simulated_measurements_are_the_model_plus_the_requested_noise(tmp_path):
    done = run("--physics", "oscillator", "--set", "zeta=0.3", "--effect", "cubic_stiffness=2", "--duration", "20",
               "--noise", "0.02", "--seed", "4", "--out", "m.csv", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    record = Record.from_csv(tmp_path / "m.csv")
    assert record.metadata["parameters"]["cubic_stiffness.k3"] == 2.0
    model = build_model("oscillator", {"zeta": 0.3}, {"cubic_stiffness": 2.0})
    t, u, y = record.batch()
    clean = simulate(model, t, u, knots=pseudorandom_knots(t)).detach()
    noise = (y - clean).pow(2).mean().sqrt() / clean.pow(2).mean().sqrt()
    assert float(noise) == pytest.approx(0.02, rel=0.1)  # 2000 samples: the sample std is within ~5 %


@pytest.mark.parametrize(
    "args, message",
    [
        (["--physics", "spring"], "unknown physics 'spring'"),
        (["--physics", "oscillator", "--effect", "cubic=2"], "unknown effect 'cubic'"),
        (["--physics", "oscillator", "--set", "zeta"], "is not NAME=NUMBER"),
        (["--physics", "oscillator", "--set", "k9=1"], "unknown parameter(s) ['k9']"),
        (["--physics", "oscillator", "--set", "zeta=-1"], "must be positive"),
    ],
)
def test_bad_arguments_exit_2_with_the_reason(tmp_path, args, message):
    done = run(*args, "--out", "m.csv", cwd=tmp_path)
    assert done.returncode == 2 and message in done.stderr
    assert not (tmp_path / "m.csv").exists()
