r"""Where a split's experiments come from: measured files, or a simulated "true system" driven by a signal.

Every source is a small typed object that YAML can spell out (``class_path``/``init_args``) and whose
:meth:`RecordSource.experiments` returns a list of :class:`~torchpaml.Record`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import torch

from torchpaml._data.record import Record
from torchpaml._errors import ConfigurationError, DataError
from torchpaml._physics.base import AbstractPhysics
from torchpaml._signals import cosine, multisine, pseudorandom, sine, time_grid
from torchpaml._simulate import Auto, simulate

__all__ = ["RecordSource", "Files", "Simulated"]


class RecordSource:
    """Abstract: a named set of experiments."""

    def experiments(self) -> list[Record]:
        raise NotImplementedError(f"{type(self).__name__} must implement experiments()")


class Files(RecordSource):
    """Measured records: CSV files (header ``t,u,y``) or NPZ files (arrays ``t``, ``u``, ``y``).

    Args:
        paths: one or more files; the suffix (``.csv`` or ``.npz``) picks the reader.
    """

    def __init__(self, paths: list[str]):
        if not paths:
            raise DataError("Files needs at least one path; list the CSV or NPZ records of this split")
        self.paths = [Path(p) for p in paths]

    def experiments(self) -> list[Record]:
        readers = {".csv": Record.from_csv, ".npz": Record.from_npz}
        records = []
        for path in self.paths:
            if path.suffix not in readers:
                raise DataError(f"{path}: unknown file type {path.suffix!r}; use a .csv (header t,u,y) or .npz file")
            records.append(readers[path.suffix](path))
        return records


#: Default relative accuracy of :class:`Simulated` measurements before noise: far below any noise a record
#: carries, and within RK4's 64 substeps where the physics has a sharp corner.
MEASUREMENT_RTOL = 1e-5


class Simulated(RecordSource):
    r"""Synthetic measurements: ``system`` (the "true" physics) driven by a seeded signal, plus output noise.

    Args:
        system: the data-generating physics, e.g. the paper's pendulum.
        signal: ``"sine"`` ($\alpha\sin\omega t$), ``"cosine"``, ``"pseudorandom"`` (the paper's: uniform
            knots every ``knot_period`` s, linearly interpolated) or ``"multisine"`` (random phases,
            ``frequencies`` in Hz).
        amplitude: $\alpha$, the peak input.
        seeds: one experiment per seed (the seed of the signal and of the noise).
        duration: record length, s.
        dt: sampling interval, s.
        omega: sine/cosine frequency, rad/s.
        noise: standard deviation of white output noise as a fraction of RMS(y), of each output channel's where
            there are several (0: noise-free).
        rtol: relative accuracy of the noise-free output (:func:`~torchpaml.simulate` with ``Auto(rtol)``: the
            step doubling for nonlinear physics; the exact path is exact). The default, :data:`MEASUREMENT_RTOL`,
            reaches sharp corners (a dead zone, Coulomb friction) within 64 substeps.
    """

    def __init__(
        self,
        system: AbstractPhysics,
        signal: Literal["sine", "cosine", "pseudorandom", "multisine"] = "pseudorandom",
        amplitude: float = 1.0,
        seeds: list[int] | None = None,
        duration: float = 80.0,
        dt: float = 0.01,
        omega: float = 1.0,
        knot_period: float = 0.8,
        frequencies: list[float] | None = None,
        noise: float = 0.0,
        rtol: float = MEASUREMENT_RTOL,
    ):
        if signal not in ("sine", "cosine", "pseudorandom", "multisine"):
            raise ConfigurationError(f"unknown signal {signal!r}; use 'sine', 'cosine', 'pseudorandom' or 'multisine'")
        if not amplitude > 0 or not noise >= 0:
            raise ConfigurationError(f"need amplitude > 0 and noise >= 0, got amplitude={amplitude}, noise={noise}")
        self.system, self.signal, self.amplitude = system, signal, float(amplitude)
        self.seeds = [0] if seeds is None else list(seeds)
        self.duration, self.dt, self.omega, self.knot_period = duration, dt, omega, knot_period
        self.frequencies = [0.1, 0.2, 0.3, 0.5, 0.7] if frequencies is None else list(frequencies)
        self.noise, self.rtol = float(noise), rtol

    def inputs(self, t: torch.Tensor) -> torch.Tensor:
        """The input of every seed, (seeds, time, 1)."""
        rows = []
        for seed in self.seeds:
            if self.signal == "sine":
                rows.append(sine(t, self.amplitude, self.omega))
            elif self.signal == "cosine":
                rows.append(cosine(t, self.amplitude, self.omega))
            elif self.signal == "pseudorandom":
                rows.append(pseudorandom(t, self.amplitude, self.knot_period, seed=seed))
            else:
                rows.append(multisine(t, self.amplitude, self.frequencies, seed=seed))
        return torch.cat(rows)

    def experiments(self) -> list[Record]:
        t = time_grid(self.duration, self.dt)
        u = self.inputs(t)
        with torch.no_grad():
            y = simulate(self.system, t, u, solver=Auto(rtol=self.rtol))
        records = []
        for i, seed in enumerate(self.seeds):
            generator = torch.Generator().manual_seed(10_000 + seed)
            scale = self.noise * (y[i].pow(2).mean(dim=0).sqrt() if y.shape[-1] > 1 else float(y[i].pow(2).mean().sqrt()))
            noisy = y[i] + scale * torch.randn(y[i].shape, generator=generator, dtype=torch.float64)
            name = f"{self.signal}-amplitude{self.amplitude:g}-seed{seed}"
            metadata = {"signal": self.signal, "amplitude": self.amplitude, "seed": seed, "noise": self.noise}
            records.append(Record(t, u[i], noisy, name, metadata))
        return records
