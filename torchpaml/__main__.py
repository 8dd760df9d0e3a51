"""``python -m torchpaml`` is the ``torchpaml`` command."""

from torchpaml.cli import main

main()
