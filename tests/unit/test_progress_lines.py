"""The command line's progress lines: the library's messages and Python's warnings, each one line on stderr."""

import logging
import re
import warnings

from torchpaml import IdentifiabilityWarning
from torchpaml.cli.progress import progress_lines


def test_a_warning_prints_as_one_progress_line_without_its_source_line(capsys):
    with progress_lines("torchpaml diagnose"):
        logging.getLogger("torchpaml.test").info("fitting")
        warnings.warn("the records do not determine zeta", IdentifiabilityWarning)
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2, lines
    assert re.fullmatch(r"torchpaml diagnose \[ *[0-9.]+ s\] IdentifiabilityWarning: the records do not determine "
                        r"zeta", lines[1]), lines


def test_warnings_are_python_warnings_again_after_the_block():
    with progress_lines("torchpaml diagnose"):
        pass
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.warn("after", IdentifiabilityWarning)
    assert [str(w.message) for w in caught] == ["after"]
