"""Bouc-Wen: a simulated hysteretic oscillator with its official test signals (``shared/data/boucwen/README.md``)."""

from torchpaml._leaderboard.benchmark import Benchmark, Published

BENCHMARK = Benchmark(
    name="boucwen", title="Bouc-Wen", folder="boucwen", train="train_multisine_forgione",
    tests=("test_multisine", "test_sinesweep"),
    metric="RMSE of the displacement, free run from rest (test_multisine: its periodic steady state)", unit="m",
    start="rest", steady_state=("test_multisine",), goal_split="test_multisine", goal=4.5e-6,
    published=(Published("7.16e-6 m", "neural state-space model", "M. Schoukens, ECC 2021; reproduced at 7.26e-6 m by "
                         "Forgione et al.", "black box"),),
    experiment="experiments/boucwen/run.py",
)
