"""Progress lines of the long commands: the library's ``logging`` messages on stderr, with the seconds since the start."""

from __future__ import annotations

import logging
import sys
import time
import warnings
from contextlib import contextmanager

__all__ = ["progress_lines"]


@contextmanager
def progress_lines(prog: str, enabled: bool = True):
    """While the block runs, the library's progress messages (``logging``, level INFO, logger ``torchpaml``) go to
    stderr as ``prog [  12.3 s] message``, and so do Python warnings (``IdentifiabilityWarning: ...``, one line
    without a source line); nothing when ``enabled`` is false. The handler is removed afterwards."""
    logger = logging.getLogger("torchpaml")
    if not enabled:
        yield
        return
    start = time.perf_counter()

    class Elapsed(logging.Formatter):
        def format(self, record: logging.LogRecord) -> str:
            return f"{prog} [{time.perf_counter() - start:7.1f} s] {record.getMessage()}"

    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(Elapsed())
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    with warnings.catch_warnings():
        warnings.showwarning = lambda message, category, *_: logger.warning("%s: %s", category.__name__, message)
        try:
            yield
        finally:
            logger.removeHandler(handler)
            logger.setLevel(level)
