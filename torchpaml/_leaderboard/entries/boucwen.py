"""Bouc-Wen: a simulated hysteretic oscillator with its official test signals (``shared/data/boucwen/README.md``)."""

from torchpaml._leaderboard.benchmark import Benchmark, Published

BENCHMARK = Benchmark(
    name="boucwen", title="Bouc-Wen", folder="boucwen", train="train_multisine_forgione",
    tests=("test_multisine", "test_sinesweep"),
    metric="RMSE of the displacement, free run from rest (test_multisine: its periodic steady state)", unit="m",
    start="rest", steady_state=("test_multisine",), goal_split="test_multisine", goal=4.5e-6,
    published=(Published("1.87e-5 m", "PNLSS with hysteresis decoupling (Esfahani et al. 2017)",
                         "as tabulated in the Hammerstein Box-Jenkins paper, Math. Probl. Eng. 2021, table 2",
                         "black box"),
               Published("4.52e-5 m", "dynoNet (Forgione & Piga 2021)",
                         "as tabulated in the Hammerstein Box-Jenkins paper, Math. Probl. Eng. 2021, table 2",
                         "black box")),
    experiment="experiments/boucwen/run.py",
)
