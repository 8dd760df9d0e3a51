"""The measured benchmarks as a contract: each one's protocol as a frozen :class:`Benchmark` (splits, metric and
unit, initialisation window, published figures with their sources, goal), their registry (:data:`BENCHMARKS`), the
fields every run writes (``<name>.json``), and the protocols' numerics (a noise floor, a periodic steady state, a
refit with one effect replaced).

    python -m torchpaml.leaderboard [--results results] [--data ../shared/data] [--only NAME ...]

runs every registered benchmark (``make leaderboard``), each into ``results/<name>``: its experiment script with
``--out results/<name>``, or, where its entry names a ``model`` and no script, the registry's own protocol
(:func:`run_benchmark`) on ``<data>/<folder>``. A new benchmark of the second kind is one entry file
(``torchpaml/_leaderboard/entries/<name>.py``, defining ``BENCHMARK = Benchmark(...)``) and its data.
"""

import argparse
import subprocess
import sys
from pathlib import Path

from torchpaml._errors import TorchpamlError
from torchpaml._leaderboard.benchmark import Benchmark, Published
from torchpaml._leaderboard.limit import MIN_REMOVED, LimitFigures, limit_of
from torchpaml._leaderboard.protocols import noise_floor, periodic_twice, with_effect
from torchpaml._leaderboard.registry import BENCHMARKS, benchmark
from torchpaml._leaderboard.result import (LIMITS, SCHEMA_VERSION, agreement_evidence, arguments, goal_entry,
                                           hybrid_entry, hypothesis_entry, ladder_entries, tried_entries,
                                           validation_agreement, write_result)
from torchpaml._leaderboard.runner import diagnosed_goal, run_benchmark
from torchpaml.cli.progress import progress_lines

__all__ = ["BENCHMARKS", "Benchmark", "LIMITS", "LimitFigures", "MIN_REMOVED", "Published", "SCHEMA_VERSION",
           "agreement_evidence", "arguments", "benchmark", "diagnosed_goal", "goal_entry", "hybrid_entry",
           "hypothesis_entry", "ladder_entries", "limit_of", "noise_floor", "periodic_twice", "run_benchmark",
           "tried_entries", "validation_agreement", "with_effect", "write_result"]


def main(argv: list[str] | None = None) -> int:
    """Run each registered benchmark in turn; the exit status of the first that fails, else 0."""
    parser = argparse.ArgumentParser(description="run every registered benchmark")
    parser.add_argument("--results", type=Path, default=Path("results"), help="where each writes <name>/")
    parser.add_argument("--data", type=Path, default=Path("..") / "shared" / "data",
                        help="the benchmarks' data folders, for those the registry's protocol runs "
                             "(default ../shared/data)")
    parser.add_argument("--only", nargs="+", action="extend", default=None,
                        help=f"these benchmarks only, of {sorted(BENCHMARKS)} (--only a b, or --only a --only b)")
    args = parser.parse_args(argv)
    chosen = [benchmark(name) for name in args.only] if args.only else list(BENCHMARKS.values())
    for entry in chosen:
        if entry.experiment is None:
            print(f"{entry.name}: the registry's protocol on {args.data / entry.folder}", flush=True)
            try:
                with progress_lines(entry.name):
                    run_benchmark(entry, args.results / entry.name, args.data / entry.folder)
            except TorchpamlError as error:  # missing files, bad records, a physics that blows up: said, not raised
                print(f"{entry.name}: {type(error).__name__}: {error}", file=sys.stderr)
                return 2
            continue
        command = [sys.executable, entry.experiment, "--out", str(args.results / entry.name), *entry.arguments]
        print(" ".join(command), flush=True)
        status = subprocess.call(command)
        if status:
            return status
    return 0


if __name__ == "__main__":
    sys.exit(main())
