"""The cascaded tanks: two tanks with square-root outflow and overflow, measured
(``shared/data/cascaded_tanks/README.md``)."""

from torchpaml._leaderboard.benchmark import Benchmark, Published

BENCHMARK = Benchmark(
    name="cascaded_tanks", title="cascaded tanks", folder="cascaded_tanks", train="estimation", tests=("test",),
    metric="RMSE of the lower level, free run from the estimation record's estimated initial state (the benchmark "
           "document: both records start from the same state)",
    unit="V", start="train", validation_share=0.25, hold="zoh", goal_split="test", goal=0.20,
    published=(Published("0.33 V", "structured neural ODE", "Forgione & Piga 2021", "black box"),
               Published("0.30 V", "CT-SUBNET, median of its runs (best run 0.217 V)",
                         "Beintema, Schoukens, Tóth, ICLR 2023", "black box",
                         caveat="early-stopped and selected on the test record"),
               Published("0.18 V", "grey box of Rogers, Holmes, Cross, Worden (2017)",
                         "as quoted by Forgione & Piga 2021", "grey box")),
    experiment="experiments/cascaded_tanks/run.py",
)
