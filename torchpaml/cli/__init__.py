"""The ``torchpaml`` command line: one entry point over three stacks, with one error rule.

- ``torchpaml fit|validate|test --config FILE.yaml`` trains through ``LightningCLI``
  (:mod:`torchpaml.cli.lightning`);
- ``torchpaml diagnose`` finds the effect a physics model is missing (jsonargparse, ``--config`` too;
  :mod:`torchpaml.cli.diagnose`), and ``torchpaml fleet`` does it for every unit of a fleet, on Ray
  (:mod:`torchpaml.cli.fleet`);
- ``torchpaml simulate`` writes measurements of library physics plus effects, and ``torchpaml paper``
  reproduces the paper (argparse; :mod:`torchpaml.cli.commands`).

**The error rule.** A mistake in the user's input (a record, a value, a name, a model that blows up)
ends the command with one line, ``torchpaml COMMAND: error: MESSAGE``, and exit status 2, whichever
stack parsed the arguments. Argument-syntax errors exit 2 through the parsers themselves.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
import traceback
from contextlib import contextmanager

from torchpaml._errors import DataError, DomainError, SimulationError

__all__ = ["USER_ERRORS", "main"]

#: Exceptions that report a mistake in the user's input; each ends a command with one line and exit status 2.
USER_ERRORS = (DataError, DomainError, SimulationError, ValueError, TypeError)
LIGHTNING_COMMANDS = ("fit", "validate", "test")


@contextmanager
def user_errors_exit(prog: str, verbose: bool = False):
    """The error rule (module docstring): a user error becomes one line on stderr and exit status 2; ``verbose``
    prints the traceback of its cause (an exception raised in the user's own physics) first."""
    try:
        yield
    except USER_ERRORS as err:
        if verbose and err.__cause__ is not None:
            traceback.print_exception(err.__cause__, file=sys.stderr)
        print(f"{prog}: error: {err}", file=sys.stderr)
        raise SystemExit(2) from None


def _command(name: str) -> Callable[[list[str], str], object]:
    if name in LIGHTNING_COMMANDS:
        from torchpaml.cli.lightning import run_lightning

        return lambda argv, prog: run_lightning(argv, prog)
    if name == "diagnose":
        from torchpaml.cli.diagnose import run_diagnose

        return lambda argv, prog: run_diagnose(argv[1:], f"{prog} diagnose")
    if name == "fleet":
        from torchpaml.cli.fleet import run_fleet

        return lambda argv, prog: run_fleet(argv[1:], f"{prog} fleet")
    from torchpaml.cli.commands import run_command

    return run_command


def main(argv: list[str] | None = None, prog: str = "torchpaml") -> None:
    """Entry point of the ``torchpaml`` console script (and of ``python -m torchpaml``)."""
    argv = sys.argv[1:] if argv is None else argv + sys.argv[1:]
    name = argv[0] if argv else ""
    with user_errors_exit(f"{prog} {name}".strip() if name in (*LIGHTNING_COMMANDS, "diagnose", "fleet") else prog,
                          verbose="--verbose" in argv):
        _command(name)(argv, prog)
