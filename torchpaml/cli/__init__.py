"""The ``torchpaml`` command line: one entry point over three stacks, with one error rule.

- ``torchpaml fit|validate|test --config FILE.yaml`` trains through ``LightningCLI``
  (:mod:`torchpaml.cli.lightning`);
- ``torchpaml diagnose`` finds the effect a physics model is missing (jsonargparse, ``--config`` too;
  :mod:`torchpaml.cli.diagnose`), and ``torchpaml fleet`` does it for every unit of a fleet, on Ray
  (:mod:`torchpaml.cli.fleet`);
- ``torchpaml simulate`` writes measurements of library physics plus effects, and ``torchpaml paper``
  reproduces the paper (argparse; :mod:`torchpaml.cli.commands`).

**The error rule.** A mistake in the user's input (a record, a value, a name, a model that blows up: the
:class:`~torchpaml.TorchpamlError` family) ends the command with one line, ``torchpaml COMMAND: error: MESSAGE``,
and exit status 2, whichever stack parsed the arguments. Argument-syntax errors exit 2 through the parsers
themselves. Any other exception is a bug in torchpaml: it is printed with its traceback and a line asking to
report it, and the command exits 1.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
import traceback
from contextlib import contextmanager

from torchpaml._errors import TorchpamlError

__all__ = ["USER_ERRORS", "main"]

#: Exceptions that report a mistake in the user's input; each ends a command with one line and exit status 2.
USER_ERRORS = (TorchpamlError,)
LIGHTNING_COMMANDS = ("fit", "validate", "test")


@contextmanager
def user_errors_exit(prog: str, verbose: bool = False):
    """The error rule (module docstring): a user error becomes one line on stderr and exit status 2 (``verbose``
    prints the traceback of its cause, an exception raised in the user's own physics, first); anything else is a
    bug, printed with its traceback, and exit status 1."""
    try:
        yield
    except USER_ERRORS as err:
        if verbose and err.__cause__ is not None:
            traceback.print_exception(err.__cause__, file=sys.stderr)
        print(f"{prog}: error: {err}", file=sys.stderr)
        raise SystemExit(2) from None
    except Exception as bug:  # noqa: BLE001 - not the user's mistake: the traceback is the report
        traceback.print_exception(bug, file=sys.stderr)
        print(f"{prog}: internal error: {type(bug).__name__} is a bug in torchpaml, not a mistake in your input; "
              "please report it to torchpaml's issue tracker with the traceback above", file=sys.stderr)
        raise SystemExit(1) from None


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
