"""The registry of the measured benchmarks: every module of :mod:`torchpaml._leaderboard.entries`, each of which
defines one ``BENCHMARK``, by name. A new benchmark is one such file and its data (its physics in the entry, run by the
registry's protocol, :mod:`~torchpaml._leaderboard.runner`), or one such file, its experiment script and its data."""

from __future__ import annotations

import importlib
import pkgutil

from torchpaml._errors import ConfigurationError
from torchpaml._leaderboard import entries
from torchpaml._leaderboard.benchmark import Benchmark

__all__ = ["BENCHMARKS", "benchmark"]


def _collect() -> dict[str, Benchmark]:
    found = {}
    for info in sorted(pkgutil.iter_modules(entries.__path__), key=lambda info: info.name):
        module = importlib.import_module(f"{entries.__name__}.{info.name}")
        if not isinstance(vars(module).get("BENCHMARK"), Benchmark):
            raise ConfigurationError(f"{module.__name__} defines no BENCHMARK = Benchmark(...): every file of "
                                     f"{entries.__name__} is one benchmark")
        found[module.BENCHMARK.name] = module.BENCHMARK
    return found


#: Every registered benchmark, by name, in the order of their files' names.
BENCHMARKS: dict[str, Benchmark] = _collect()


def benchmark(name: str) -> Benchmark:
    """The registered benchmark ``name``; a :class:`~torchpaml.ConfigurationError` naming the others otherwise."""
    if name not in BENCHMARKS:
        raise ConfigurationError(f"unknown benchmark {name!r}; registered: {sorted(BENCHMARKS)}")
    return BENCHMARKS[name]
