"""C source compiled into a shared library with the system's compiler: what the FMU, the tracker's filter and the
compiled simulation run."""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import stat
import subprocess
import tempfile
from pathlib import Path

from torchpaml._errors import ConfigurationError

__all__ = ["UnbuildableError", "cache_folder", "cached_library", "compile_library", "compiler", "loaded"]

#: ``-ffp-contract=off``: no fused multiply-adds, so a library gives the same numbers on every machine.
FLAGS = ("-shared", "-fPIC", "-O2", "-ffp-contract=off")
#: Seconds a compile may take before it is given up (a compiler that hangs).
COMPILE_SECONDS = 120


class UnbuildableError(ConfigurationError):
    """This machine cannot build or load a library: no compiler, a source that does not compile, a compile that
    hangs, a cache folder that is not the user's own or cannot be written, a library that does not load. The
    compiled simulation falls back to the engine on it; an FMU or a filter that needs C refuses."""


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
        raise UnbuildableError(f"{purpose} compiles C, and no C compiler (cc, gcc) is on PATH; install one")
    try:
        library.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=library.parent) as folder:  # beside the library: the rename is atomic
            code, built = Path(folder) / "source.c", Path(folder) / library.name
            code.write_text(source)
            flags = [] if include is None else [f"-I{include}"]
            done = subprocess.run([cc, *FLAGS, *flags, "-o", str(built), str(code), "-lm"], capture_output=True,
                                  text=True, timeout=COMPILE_SECONDS)
            if done.returncode != 0:
                first = (done.stderr.strip().splitlines() or ["no message"])[0]
                raise UnbuildableError(f"{purpose}: the C source did not compile ({first}); report it with the model")
            os.replace(built, library)
    except subprocess.TimeoutExpired:
        raise UnbuildableError(f"{purpose}: the C compiler {cc} ran past {COMPILE_SECONDS} s; check it compiles a "
                               "small file") from None
    except OSError as error:
        raise UnbuildableError(f"{purpose}: {library.parent} cannot be written ({error.strerror}); set XDG_CACHE_HOME "
                               "to a folder of your own") from None
    return library


def loaded(library: Path) -> ctypes.CDLL:
    """``library`` loaded; :class:`UnbuildableError` where it does not load (a folder mounted noexec, a library built
    for another machine)."""
    try:
        return ctypes.CDLL(str(library))
    except OSError as error:
        raise UnbuildableError(f"{library} does not load ({str(error)[:160]}); remove it, or set XDG_CACHE_HOME to a "
                               "folder of your own on an executable file system") from None


def cache_folder() -> Path:
    """The user's own folder of compiled libraries: ``$XDG_CACHE_HOME/torchpaml/compiled`` (``~/.cache`` by
    default), created owner-only (mode 0700). It is used only while it belongs to this user and no one else can write
    to it; otherwise :class:`~torchpaml.ConfigurationError` says which folder and how to fix it. There is no shared
    fallback: a library in a folder that others can write could be planted there, and loading it runs its code."""
    folder = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "torchpaml" / "compiled"
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError as error:
        raise UnbuildableError(f"the compiled-library cache {folder} cannot be created ({error.strerror}); set "
                                 "XDG_CACHE_HOME to a folder of your own") from None
    _check_owned(folder, "the compiled-library cache")
    return folder


def _check_owned(path: Path, what: str) -> None:
    """``path`` belongs to this user and neither its group nor others can write it."""
    status = path.stat()
    if status.st_uid != os.getuid() or status.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        raise UnbuildableError(f"{what} {path} belongs to another user or others can write to it (mode "
                                 f"{stat.filemode(status.st_mode)}); a library there could have been planted: remove "
                                 "it, or set XDG_CACHE_HOME to a folder of your own")


def cached_library(source: str, name: str, purpose: str) -> Path:
    """``source`` compiled once per machine (:func:`compile_library`), kept under :func:`cache_folder` as
    ``NAME_DIGEST.so`` where DIGEST is the SHA-256 of the source, the compiler's path, :data:`FLAGS` and the machine
    (its architecture and system: a cache folder shared by two kinds of machine keeps a library for each); later calls
    load that file once it is checked to be the user's own and written by no one else."""
    key = "\0".join((source, str(compiler()), *FLAGS, platform.machine(), platform.system()))
    library = cache_folder() / f"{name}_{hashlib.sha256(key.encode()).hexdigest()[:16]}.so"
    if library.exists():
        _check_owned(library, "the compiled library")
        return library
    return compile_library(source, library, purpose)
