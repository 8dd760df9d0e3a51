"""A user's first-order physics: two tanks with a hidden Torricelli outflow, simulated, found and added.

Truth: the two-tank physics of ``experiments/cascaded_tanks/tanks.py`` (k1 = 0.02, k2 = 0.01,
k3 = 0.01, k4 = 0.05 1/s) with the lower tank's outflow k3 x2 bent into Torricelli's k3 sqrt(x2) (g = 1), started away from
rest at levels (6, 4). Inputs: 3 V plus pseudorandom knots every 40 s (+-1.5 V), 1200 s at 4 s, with
1 % output noise. The diagnosed physics starts 50 % off with k2 fixed (see the experiment), and the
initial state is estimated; the two best-scored candidates are refitted.
"""

import pytest

import torch

from experiment_modules import load
from torchpaml import Estimate, Ranker, Record, diagnose, mismatch, pseudorandom, time_grid

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane

tanks = load("cascaded_tanks/tanks.py")
X0 = torch.tensor([[6.0, 4.0]], dtype=torch.float64)


def record(system, seed: int, noise: float) -> tuple[Record, float]:
    t = time_grid(1200.0, 4.0)
    u = 3.0 + pseudorandom(t, 1.5, period=40.0, seed=seed)
    with torch.no_grad():
        y = system(t, u, X0)[0]
    generator = torch.Generator().manual_seed(100 + seed)
    noisy = y + noise * y.std() * torch.randn(y.shape, generator=generator, dtype=torch.float64)
    return Record(t, u[0], noisy, f"seed {seed}"), mismatch(noisy, y)


def test_the_hidden_sqrt_outflow_is_found_and_brings_the_error_to_the_noise_floor():
    truth = tanks.TwoTanks(0.02, 0.01, 0.01, 0.05) + tanks.TorricelliOutflow(1.0, tank="lower")
    train, _ = record(truth, seed=0, noise=0.01)
    validation, floor = record(truth, seed=1, noise=0.01)
    physics = tanks.TwoTanks(0.03, 0.01, 0.015, 0.03, learn=("k1", "k3", "k4"))
    candidates = [tanks.TorricelliOutflow(tank="upper"), tanks.TorricelliOutflow(tank="lower"), tanks.SensorClip()]
    diagnosis = diagnose(physics, candidates, train, validation, initial_state=Estimate(), ranker=Ranker(shortlist=2))
    assert diagnosis.ladder.added[0] == "sqrt_outflow_lower"
    final = diagnosis.ladder.final
    assert final.nrmse_validation < 1.5 * floor < diagnosis.baseline.nrmse_validation
    assert abs(final.parameters["sqrt_outflow_lower.g"] - 1.0) < 0.1  # the square-root law
    assert abs(float(final.train_states[0][1]) - 4.0) < 0.05 * 4.0  # the measured (lower) level
