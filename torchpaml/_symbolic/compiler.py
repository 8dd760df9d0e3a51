"""C source compiled into a shared library with the system's compiler: what the FMU, the tracker's filter and the
compiled simulation run."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from torchpaml._errors import ConfigurationError

__all__ = ["cached_library", "compile_library", "compiler"]

#: ``-ffp-contract=off``: no fused multiply-adds, so a library gives the same numbers on every machine.
FLAGS = ("-shared", "-fPIC", "-O2", "-ffp-contract=off")


def compiler() -> str | None:
    """The system's C compiler (``cc``, else ``gcc``) on PATH, ``None`` where there is none."""
    return shutil.which("cc") or shutil.which("gcc")


def compile_library(source: str, library: Path, purpose: str, include: Path | None = None) -> Path:
    """Compile ``source`` (C99) into the shared library ``library`` (``cc`` with :data:`FLAGS`, ``include`` on the
    header path); ``purpose`` (e.g. "writing an FMU") names what needs it in the one-line refusals: no compiler on
    PATH, or a source that does not compile. The library appears whole or not at all (built in a folder beside it, then
    renamed: processes that compile the same model at once each load a whole file)."""
    cc = compiler()
    if cc is None:
        raise ConfigurationError(f"{purpose} compiles C, and no C compiler (cc, gcc) is on PATH; install one")
    library.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=library.parent) as folder:  # beside the library: the rename is atomic
        code, built = Path(folder) / "source.c", Path(folder) / library.name
        code.write_text(source)
        flags = [] if include is None else [f"-I{include}"]
        done = subprocess.run([cc, *FLAGS, *flags, "-o", str(built), str(code), "-lm"], capture_output=True, text=True)
        if done.returncode != 0:
            first = (done.stderr.strip().splitlines() or ["no message"])[0]
            raise ConfigurationError(f"{purpose}: the C source did not compile ({first}); report it with the model")
        os.replace(built, library)
    return library


def _cache() -> Path:
    """``$XDG_CACHE_HOME/torchpaml/compiled`` (``~/.cache`` by default), or a temporary folder where that cannot be
    written."""
    folder = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "torchpaml" / "compiled"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        folder = Path(tempfile.gettempdir()) / "torchpaml-compiled"
        folder.mkdir(parents=True, exist_ok=True)
    return folder


def cached_library(source: str, name: str, purpose: str) -> Path:
    """``source`` compiled once per machine (:func:`compile_library`), kept under the cache folder as
    ``NAME_DIGEST.so`` where DIGEST is the SHA-256 of the source; later calls load that file."""
    digest = hashlib.sha256(source.encode()).hexdigest()[:16]
    library = _cache() / f"{name}_{digest}.so"
    return library if library.exists() else compile_library(source, library, purpose)
