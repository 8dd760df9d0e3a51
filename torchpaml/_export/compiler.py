"""C source compiled into a shared library with the system's compiler: what the FMU and the tracker's filter run."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from torchpaml._errors import ConfigurationError

__all__ = ["compile_library"]


def compile_library(source: str, library: Path, purpose: str, include: Path | None = None) -> Path:
    """Compile ``source`` (C99) into the shared library ``library`` (``cc -shared -fPIC -O2``, ``include`` on the
    header path); ``purpose`` (e.g. "writing an FMU") names what needs it in the one-line refusals: no compiler on
    PATH, or a source that does not compile. The library appears whole or not at all (built aside, then moved)."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise ConfigurationError(f"{purpose} compiles C, and no C compiler (cc, gcc) is on PATH; install one")
    with tempfile.TemporaryDirectory() as folder:
        code, built = Path(folder) / "source.c", Path(folder) / library.name
        code.write_text(source)
        flags = [] if include is None else [f"-I{include}"]
        done = subprocess.run([compiler, "-shared", "-fPIC", "-O2", *flags, "-o", str(built), str(code), "-lm"],
                              capture_output=True, text=True)
        if done.returncode != 0:
            first = (done.stderr.strip().splitlines() or ["no message"])[0]
            raise ConfigurationError(f"{purpose}: the C source did not compile ({first}); report it with the model")
        library.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(built), library)
    return library
