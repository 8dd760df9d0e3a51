"""Silverbox: an electronic Duffing oscillator, measured (``shared/data/silverbox/README.md``)."""

from torchpaml._leaderboard.benchmark import Benchmark, Published

BENCHMARK = Benchmark(
    name="silverbox", title="Silverbox", folder="silverbox", train="train_multisine",
    tests=("test_multisine", "test_arrow_no_extrapolation", "test_arrow_full"),
    metric="RMSE of the output, free run", unit="mV", scale=1000.0, init_window=50, start="window",
    goal_split="test_multisine", goal=0.33,
    published=(Published("0.310 mV", "GRU", "tsfast workshop 2025", "black box"),),
    experiment="experiments/silverbox/run.py", arguments=("--discover",),
)
