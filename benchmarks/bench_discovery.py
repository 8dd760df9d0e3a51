"""How discovery's time grows with the record's length, against one physics fit measured in the same run.

    python benchmarks/bench_discovery.py [--lengths 600 6000 60000]

Data: the oscillator with a hidden cubic damping (the discovery cases' first), 20 Hz, 2 % noise, a
pseudorandom training record and a multisine validation record of each length. For each length: one
fit of the physics alone (the baseline, linear: exact simulation), and the discovery alone on it
(:func:`~torchpaml.discover_missing_force` after a ranking with no candidates). Reported: seconds,
microseconds per sample, the discovery's ratio to the physics fit, and its time per sample against the
shortest record's (1.0 is linear in N). One thread.
"""

import argparse
import time

import torch
from torchpaml import Oscillator, Simulated, discover_missing_force, fit_physics, rank_missing_effects

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "discovery"))
from forces import CubicDamping  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="+", default=[600, 6000, 60000])
    lengths = parser.parse_args().lengths
    torch.set_num_threads(1)
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CubicDamping(0.5)
    print("| samples | physics fit s | discovery s | µs per sample | discovery / fit | per sample vs first | found |")
    print("|---|---|---|---|---|---|---|")
    first = None
    for n in lengths:
        duration = n * 0.05
        train = Simulated(truth, "pseudorandom", 1.0, [0], duration, 0.05, noise=0.02).experiments()
        validation = Simulated(truth, "multisine", 1.0, [1], duration, 0.05, noise=0.02).experiments()

        def physics():
            return Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain"))

        start = time.perf_counter()
        fit_physics(physics(), train)
        fit = time.perf_counter() - start
        start = time.perf_counter()
        ranking = rank_missing_effects(physics(), [], train, validation)
        found = discover_missing_force(ranking, train, validation)
        seconds = time.perf_counter() - start
        per = seconds / len(train[0].t)
        first = first or per
        print(f"| {len(train[0].t)} | {fit:.2f} | {seconds:.1f} | {1e6 * per:.0f} | {seconds / fit:.0f}x | "
              f"{per / first:.2f} | `{found.expression}` |", flush=True)


if __name__ == "__main__":
    main()
