"""Cost of ranking every library effect, against one physics fit measured in the same run.

    python benchmarks/bench_ranking.py [--repeats 5]

Data: an oscillator with a hidden cubic stiffness, 30 s at 20 Hz, 2 % noise (the hidden-effect tests' case).
Baselines, fitted by the same trust-region least squares:
- one fit of the physics alone (linear: exact simulation);
- one fit of the physics plus the true effect (nonlinear: RK4), the fit a user makes who already knows the effect.
Rankings: the default (first-order scores of every library candidate, refit of the best 2) and the
exhaustive one (refit of all). The four are timed in turn, ``--repeats`` rounds; each time is the best of its rounds
(the machine's noise only adds), and the ranking's ratio to the fit is also given within each round, where
both saw the same machine. One thread.
"""

import argparse
import copy
import time

import torch

from torchpaml import CubicStiffness, Oscillator, Simulated, default_effects, fit_physics
from torchpaml.analysis import rank_missing_effects


def timed(work) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    repeats = parser.parse_args().repeats
    torch.set_num_threads(1)
    true = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CubicStiffness(2.0)
    train = Simulated(true, "pseudorandom", 1.5, [0], 30.0, 0.05, noise=0.02).experiments()[0]
    validation = Simulated(true, "multisine", 1.5, [1], 30.0, 0.05, noise=0.02).experiments()[0]
    physics = Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain"))
    count = len(default_effects())
    fitted = copy.deepcopy(physics)
    fit_physics(fitted, train)  # untimed: the first call pays torch's one-time warm-up (about 2 s)
    works = {
        "linear": lambda: fit_physics(copy.deepcopy(physics), train),
        "nonlinear": lambda: fit_physics(copy.deepcopy(fitted) + CubicStiffness(), train),
        "ranking": lambda: rank_missing_effects(physics, default_effects(), train, validation),
        "exhaustive": lambda: rank_missing_effects(physics, default_effects(), train, validation, shortlist=count),
    }
    rounds = [{name: timed(work) for name, work in works.items()} for _ in range(repeats)]  # interleaved
    linear, nonlinear, ranking, exhaustive = (min(r[name] for r in rounds) for name in works)
    ratios = sorted(r["ranking"] / r["nonlinear"] for r in rounds)
    print(f"one fit of the physics (linear, exact):          {linear:7.2f} s")
    print(f"one fit of physics + the true effect (RK4):      {nonlinear:7.2f} s")
    print(f"ranking {count} candidates, 2 refitted (default):     {ranking:7.2f} s = {ranking / nonlinear:.1f} x the "
          f"physics + effect fit, {ranking / linear:.0f} x the linear fit")
    print(f"  the same ratio within each round: median {ratios[len(ratios) // 2]:.1f} x, from {ratios[0]:.1f} to "
          f"{ratios[-1]:.1f} x")
    print(f"ranking {count} candidates, all refitted:             {exhaustive:7.2f} s = {exhaustive / nonlinear:.1f} x "
          f"the physics + effect fit; the shortlist saves {exhaustive / ranking:.1f} x")

if __name__ == "__main__":
    main()
