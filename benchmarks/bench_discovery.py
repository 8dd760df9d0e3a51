"""How discovery's time grows with the record's length, against one physics fit measured in the same run.

    python benchmarks/bench_discovery.py [--lengths 600 6000 60000] [--perturbed SEED ...]

Data: the oscillator with a hidden cubic damping (the discovery cases' first), 20 Hz, 2 % noise, a
pseudorandom training record and a multisine validation record of each length. For each length: one
fit of the physics alone (the baseline, linear: exact simulation), and the discovery alone on it
(:func:`~torchpaml.analysis.discover_missing_force` after a ranking with no candidates). Reported: seconds,
microseconds per sample, the discovery's ratio to the physics fit, and its time per sample against the
shortest record's (1.0 is linear in N). One thread. With ``--perturbed``, the same again on the records perturbed
by 1e-12 relative with each seed (``bench_same_answer.perturbed``: the training record with the seed, the validation
record with the next): whether the discovery finds the same form on another machine's rounding.
"""

import argparse
import sys
from pathlib import Path

import torch
from bench_diagnosis import physics, rows_by_length
from bench_same_answer import perturbed
from torchpaml import Oscillator
from torchpaml.analysis import discover_missing_force, rank_missing_effects

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "discovery"))
from forces import CubicDamping  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="+", default=[600, 6000, 60000])
    parser.add_argument("--perturbed", type=int, nargs="*", default=[], help="seeds of records perturbed by 1e-12")
    torch.set_num_threads(1)
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CubicDamping(0.5)

    def work(train, validation):
        ranking = rank_missing_effects(physics(), [], train, validation)
        return f"`{discover_missing_force(ranking, train, validation).text}`"

    args = parser.parse_args()
    rows_by_length(truth, args.lengths, "discovery", work)
    for seed in args.perturbed:
        print(f"\nrecords perturbed by 1e-12, seed {seed}")
        rows_by_length(truth, args.lengths, "discovery", lambda train, validation, seed=seed: work(
            [perturbed(r, seed) for r in train], [perturbed(r, seed + 1) for r in validation]))


if __name__ == "__main__":
    main()
