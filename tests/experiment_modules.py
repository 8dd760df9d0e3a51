"""Import the user code that lives beside the experiments (their physics and effects), as a user's script would."""

import importlib.util
import sys
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def load(relative: str):
    """The module at ``experiments/<relative>``, imported under its file name."""
    path = EXPERIMENTS / relative
    sys.path.insert(0, str(path.parent))
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
