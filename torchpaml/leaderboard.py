"""The measured benchmarks as a contract: each one's protocol as a frozen :class:`Benchmark` (splits, metric and
unit, initialisation window, published figures with their sources, goal), their registry (:data:`BENCHMARKS`), the
fields every run writes (``<name>.json``), and the protocols' numerics (a noise floor, a periodic steady state, a
refit with one effect replaced).

    python -m torchpaml.leaderboard [--results results] [--only NAME ...]

runs every registered benchmark's experiment (``make leaderboard``), each with ``--out results/<name>``.
"""

import argparse
import subprocess
import sys
from pathlib import Path

from torchpaml._leaderboard.benchmark import Benchmark, Published
from torchpaml._leaderboard.protocols import noise_floor, periodic_twice, with_effect
from torchpaml._leaderboard.registry import BENCHMARKS, benchmark
from torchpaml._leaderboard.result import (LIMITS, SCHEMA_VERSION, arguments, goal_entry, hybrid_entry,
                                           ladder_entries, tried_entries, write_result)

__all__ = ["BENCHMARKS", "Benchmark", "LIMITS", "Published", "SCHEMA_VERSION", "arguments", "benchmark", "goal_entry",
           "hybrid_entry", "ladder_entries", "noise_floor", "periodic_twice", "tried_entries", "with_effect",
           "write_result"]


def main(argv: list[str] | None = None) -> int:
    """Run each registered benchmark's experiment in turn; the exit status of the first that fails, else 0."""
    parser = argparse.ArgumentParser(description="run every registered benchmark's experiment")
    parser.add_argument("--results", type=Path, default=Path("results"), help="where each writes <name>/")
    parser.add_argument("--only", nargs="*", default=None, help=f"these benchmarks only, of {sorted(BENCHMARKS)}")
    args = parser.parse_args(argv)
    chosen = [benchmark(name) for name in args.only] if args.only else list(BENCHMARKS.values())
    for entry in chosen:
        command = [sys.executable, entry.experiment, "--out", str(args.results / entry.name), *entry.arguments]
        print(" ".join(command), flush=True)
        status = subprocess.call(command)
        if status:
            return status
    return 0


if __name__ == "__main__":
    sys.exit(main())
