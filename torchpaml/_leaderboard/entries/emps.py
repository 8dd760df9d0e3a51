"""EMPS: an electro-mechanical positioning system under position control, measured (``shared/data/emps/README.md``)."""

from torchpaml._leaderboard.benchmark import Benchmark, Published

BENCHMARK = Benchmark(
    name="emps", title="EMPS", folder="emps", train="estimation", tests=("test",),
    metric="RMSE of the position, free run from vir", unit="mm", scale=1000.0, init_window=20, start="window",
    goal_split="test", goal=4.6, velocity="velocity",
    published=(Published("4.61 mm", "CT-SUBNET", "its notebooks' outputs (Beintema, Schoukens, Tóth, ICLR 2023)",
                         "black box"),),
    experiment="experiments/emps/run.py",
)
