"""The ``torchpaml`` command line. Errors in the user's input exit non-zero with a one-line message.

``torchpaml fit|validate|test --config FILE.yaml`` trains through ``LightningCLI``
(:mod:`torchpaml.training.cli`); ``torchpaml paper`` reproduces the paper.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from torchpaml.errors import DataError, DomainError, SimulationError

__all__ = ["main"]


def _paper(args: argparse.Namespace) -> None:
    from torchpaml.paper import format_table, reproduce

    start = time.perf_counter()
    report = reproduce(args.alpha or [4.0, 10.0], seeds=args.seeds)
    report["wall_time_s"] = time.perf_counter() - start
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(report, indent=2))
    table = format_table(report)
    (out / "table.md").write_text(table + "\n")
    print(table)
    print(f"\n{args.seeds} seed(s), {report['wall_time_s']:.1f} s; wrote {out / 'results.json'} and {out / 'table.md'}")


def _paper_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--alpha", type=float, action="append", help="input amplitude (repeat for several)")
    parser.add_argument("--seeds", type=int, default=10, help="number of pseudorandom seeds (default 10)")
    parser.add_argument("--out", required=True, help="output folder for results.json and table.md")
    parser.set_defaults(run=_paper)


LIGHTNING_COMMANDS = ("fit", "validate", "test")


def _lightning(argv: list[str], prog: str) -> None:
    from torchpaml.training.cli import run_lightning

    try:
        run_lightning(argv)
    except (DataError, DomainError, SimulationError) as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        raise SystemExit(2) from None


def main(argv: list[str] | None = None, prog: str = "torchpaml") -> None:
    """Entry point of the ``torchpaml`` console script."""
    argv = sys.argv[1:] if argv is None else argv + sys.argv[1:]
    if argv and argv[0] in LIGHTNING_COMMANDS:
        _lightning(argv, prog)
        return
    parser = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True)
    _paper_arguments(commands.add_parser("paper", help="reproduce the paper's numerical results"))
    args = parser.parse_args(argv)
    if args.command == "paper" and args.seeds < 1:
        parser.error("--seeds must be at least 1")
    try:
        args.run(args)
    except (DataError, DomainError, SimulationError, ValueError) as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        raise SystemExit(2) from None
