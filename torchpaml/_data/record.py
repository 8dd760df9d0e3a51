"""Records: measured or simulated input/output records, with validated CSV and NPZ I/O."""

from __future__ import annotations

import io
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from torchpaml._errors import DataError
from torchpaml._grid import check_hold, uniform_step

__all__ = ["Record"]

_COLUMNS = ("t", "u", "y")


def _metadata(line: str, path: Path) -> dict:
    """The metadata of a CSV's first line, ``# {...}``: a JSON object, read as data (``json.loads``, nothing run)."""
    text = line.lstrip("#").strip() or "{}"
    try:
        metadata = json.loads(text)
    except json.JSONDecodeError as err:
        raise DataError(f"{path}: its first line starts with '#', so it is read as the record's metadata, a JSON "
                        f"object such as '# {{\"hold\": \"zoh\"}}', but it is not JSON ({err.msg} at column "
                        f"{err.colno}); repair it or delete the line") from None
    if not isinstance(metadata, dict):
        raise DataError(f"{path}: its first line's metadata must be a JSON object ({{...}}), got "
                        f"{type(metadata).__name__}; repair it or delete the line")
    return metadata


@dataclass
class Record:
    """One record of a device: time t (time,) in s, input u (time, n_u), output y (time, n_y), float64.

    ``hold`` says how the input moved between samples: ``"foh"`` (linearly, the default) or ``"zoh"``
    (held constant until the next sample, as a DAC plays a sampled signal); every simulation of the
    record (fits, rankings, scores) holds it so.

    ``validate`` runs on construction: the lengths agree, values are finite, time strictly increases.
    Use :meth:`batch` to get the (1, time, channel) tensors the models take.
    """

    t: torch.Tensor
    u: torch.Tensor
    y: torch.Tensor
    name: str = "record"
    metadata: dict = field(default_factory=dict)
    hold: str = "foh"

    def __post_init__(self):
        self.t = torch.as_tensor(self.t, dtype=torch.float64).detach().reshape(-1)
        self.u = _as_columns(self.u, "u")
        self.y = _as_columns(self.y, "y")
        check_hold(self.hold)
        self.validate()

    def validate(self) -> None:
        """Raise :class:`DataError` naming the problem and its fix."""
        where = f"record {self.name!r}"
        if len(self.t) == 0:
            raise DataError(f"{where} is empty: it has no samples; check the file or the slicing that made it")
        if not (len(self.t) == len(self.u) == len(self.y)):
            raise DataError(
                f"{where}: length mismatch, t has {len(self.t)} samples, u {len(self.u)}, y {len(self.y)}; "
                "every column needs one value per time sample"
            )
        columns = [("t", self.t[:, None])] + [(name, values[:, [i]]) for letter, key, values in (
            ("u", "inputs", self.u), ("y", "outputs", self.y)) for i, name in enumerate(_column_names(
                self.metadata.get(key), letter, values.shape[1]))]
        gaps = bool(self.metadata.get("missing_outputs"))
        for column, values in columns:
            bad = ~torch.isfinite(values[:, 0])
            if gaps and column not in ("t", *_column_names(self.metadata.get("inputs"), "u", self.u.shape[1])):
                bad = torch.isinf(values[:, 0])  # a missing output sample (NaN) is allowed where the metadata says so
            if bool(bad.any()):
                row = int(bad.nonzero()[0])
                raise DataError(
                    f"{where}: column {column!r} has {int(bad.sum())} NaN/inf value(s), first at row {row}; "
                    "drop or interpolate those samples before fitting"
                )
        steps = torch.diff(self.t)
        if bool((steps <= 0).any()):
            row = int((steps <= 0).nonzero()[0]) + 1
            raise DataError(
                f"{where}: time must be strictly increasing, but t[{row}] = {float(self.t[row]):.6g} s follows "
                f"t[{row - 1}] = {float(self.t[row - 1]):.6g} s; sort the rows and remove duplicate time stamps"
            )

    @property
    def elapsed(self) -> torch.Tensor:
        """The sample times from the first, $t - t_0$, (time,): the time every simulation of the record runs on."""
        return self.t - self.t[0]

    @property
    def output_names(self) -> list[str]:
        """The output channels' names: those the metadata declares (``"outputs"``), else ``y`` (one) or ``y1, y2, …``."""
        return _names(self.metadata.get("outputs"), "y", self.y.shape[1])

    @property
    def input_names(self) -> list[str]:
        """The input channels' names: those the metadata declares (``"inputs"``), else ``u`` (one) or ``u1, u2, …``."""
        return _names(self.metadata.get("inputs"), "u", self.u.shape[1])

    @property
    def dt(self) -> float:
        """The sampling interval; raises :class:`DataError` if the sampling is not uniform."""
        try:
            return uniform_step(self.t)
        except DataError as err:
            raise DataError(f"record {self.name!r}: {err}") from None

    def require_uniform(self, purpose: str) -> float:
        """The sampling interval; a :class:`DataError` that names the gaps and the fix if it is not uniform."""
        steps = torch.diff(self.t)
        usual = float(steps.median())
        gaps = (steps - usual).abs() > 1e-6 * usual
        if not bool(gaps.any()):
            return usual
        first = int(gaps.nonzero()[0])
        raise DataError(
            f"record {self.name!r} is not uniformly sampled: {int(gaps.sum())} of its {len(steps)} steps differ "
            f"from the usual {usual:.6g} s (from {float(steps.min()):.6g} to {float(steps.max()):.6g} s), the first "
            f"between t = {float(self.t[first]):.6g} and {float(self.t[first + 1]):.6g} s. {purpose} needs uniform "
            "sampling: resample the record onto a uniform grid, or use model_ladder / rank_missing_effects, which "
            "simulate records with missing samples directly"
        )

    def window(self, start: int | None = None, stop: int | None = None, name: str | None = None) -> Record:
        """Samples ``start:stop`` as a record of their own (named ``name``, else this one's), with its hold."""
        return Record(self.t[start:stop], self.u[start:stop], self.y[start:stop], name or self.name, self.metadata,
                      self.hold)

    def batch(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(t (time,), u (1, time, n_u), y (1, time, n_y))``."""
        return self.t, self.u[None], self.y[None]

    @classmethod
    def records(cls, t: torch.Tensor, u: torch.Tensor, y: torch.Tensor, name: str = "record") -> list[Record]:
        """One experiment per batch row of t (time,), u (batch, time, n_u), y (batch, time, n_y)."""
        return [cls(t, u[i], y[i], f"{name}{i}") for i in range(u.shape[0])]

    # -- I/O ---------------------------------------------------------------------------------
    @classmethod
    def from_csv(cls, path: str | Path, name: str | None = None, hold: str | None = None,
                 channels: tuple[Sequence[str], Sequence[str]] | None = None, with_outputs: bool = True,
                 missing_outputs: bool = False) -> Record:
        """Read a CSV whose header holds ``t`` and the channels (a first ``# {json}`` line is metadata; extra columns
        are ignored):

        * ``t,u,y``: one input and one output;
        * ``t,u1,u2,…,y1,y2,…``: several, in the order of their numbers;
        * named channels, declared in the metadata, e.g. ``# {"inputs": ["force"], "outputs": ["x1", "x2"]}``;
        * named channels that ``channels`` expects, ``(input names, output names)`` (a physics' ``input_names`` and
          ``output_names``), as data loggers write them: ``t,force,x1,x2`` with no metadata line.

        ``hold``: how the input moved between samples; default the metadata's ``"hold"``, else ``"foh"``.
        ``with_outputs=False``: a file of inputs alone (a model's prediction needs no outputs): where its output
        columns are missing, ``y`` is zeros, one column per expected output, and the metadata says
        ``"outputs_missing": true``.
        ``missing_outputs=True``: a stream whose output cells may be empty or NaN (a measurement that did not
        arrive; a tracker predicts through it): they are read as NaN, and the metadata's ``"missing_outputs"`` counts
        the samples with one (a fit refuses such a record); time and inputs must still be numbers."""
        path = Path(path)
        if not path.exists():
            raise DataError(f"no such file: {path}" + ("" if path.is_absolute() else f" (in the folder {Path.cwd()})"))
        lines = path.read_text().splitlines()
        metadata = {}
        if lines and lines[0].startswith("#"):
            metadata = _metadata(lines[0], path)
            lines = lines[1:]
        if not lines or not lines[0].strip():
            raise DataError(f"{path} is empty; expected a header 't,u,y' followed by one row per sample")
        header = [h.strip() for h in lines[0].split(",")]
        missing = not with_outputs and not _has_outputs(header, metadata, channels)
        if missing:
            expected = list(channels[1]) if channels and channels[1] else metadata.get("outputs", ["y"])
            header_names = [*header, *expected]
            metadata = {**metadata, "outputs_missing": True}
        inputs, outputs = _channels(header_names if missing else header, metadata, path, channels)
        for key, names, given in (("inputs", inputs, channels[0] if channels else ()),
                                  ("outputs", outputs, channels[1] if channels else ())):
            if key not in metadata and given and names == list(given):
                metadata = {**metadata, key: names}  # the record names them as its header does
        rows = [r for r in lines[1:] if r.strip()]
        if not rows:
            raise DataError(f"{path} has a header but no data rows")
        try:
            table = np.array([[float(v) if v.strip() or not missing_outputs else np.nan for v in r.split(",")]
                              for r in rows], dtype=np.float64)
        except ValueError as err:
            raise DataError(f"{path}: a value is not a number ({err}); every cell must parse as a float") from None
        if table.ndim != 2 or table.shape[1] != len(header):
            raise DataError(f"{path}: every row must have {len(header)} values like the header")
        columns = {h: table[:, i] for i, h in enumerate(header)}
        columns.update({name: np.zeros(len(table)) for name in outputs if missing})
        gaps = int(np.isnan(np.stack([columns[c] for c in outputs], axis=1)).any(axis=1).sum())
        if missing_outputs and gaps:
            metadata = {**metadata, "missing_outputs": gaps}
        return cls(columns["t"], np.stack([columns[c] for c in inputs], axis=1),
                   np.stack([columns[c] for c in outputs], axis=1), name or path.stem, metadata,
                   hold or metadata.get("hold", "foh"))

    def _written_metadata(self) -> dict:
        """The metadata a file keeps: this record's, with its ``hold`` where it is not the default."""
        return self.metadata if self.hold == "foh" else {**self.metadata, "hold": self.hold}

    def to_csv(self, path: str | Path) -> Path:
        """Write the header ``t,u,y`` (one input and one output), ``t,u1,…,y1,…`` (several), or the channels' names
        where the metadata declares them (``inputs``, ``outputs``), with the metadata as a first ``# {json}`` line;
        :meth:`from_csv` reads it back."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        metadata = self._written_metadata()
        names = [*_names(metadata.get("inputs"), "u", self.u.shape[1]), *_names(metadata.get("outputs"), "y",
                                                                                    self.y.shape[1])]
        table = torch.cat([self.t[:, None], self.u, self.y], dim=1).numpy()
        buffer = io.StringIO()
        np.savetxt(buffer, table, delimiter=",", fmt="%.17g")
        head = f"# {json.dumps(metadata)}\n" if metadata else ""
        path.write_text(f"{head}{','.join(['t', *names])}\n{buffer.getvalue()}")
        return path

    @classmethod
    def from_npz(cls, path: str | Path, name: str | None = None, hold: str | None = None) -> Record:
        """Read arrays ``t``, ``u``, ``y`` (and optional JSON ``metadata``) from an NPZ file; ``hold`` as in
        :meth:`from_csv`."""
        path = Path(path)
        if not path.exists():
            raise DataError(f"no such file: {path}" + ("" if path.is_absolute() else f" (in the folder {Path.cwd()})"))
        with np.load(path, allow_pickle=False) as archive:
            missing = [c for c in _COLUMNS if c not in archive.files]
            if missing:
                raise DataError(f"{path}: missing array(s) {missing}; it holds {archive.files}, expected t, u, y")
            metadata = json.loads(str(archive["metadata"])) if "metadata" in archive.files else {}
            return cls(archive["t"], archive["u"], archive["y"], name or path.stem, metadata,
                       hold or metadata.get("hold", "foh"))

    def to_npz(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, t=self.t.numpy(), u=self.u.numpy(), y=self.y.numpy(),
                 metadata=json.dumps(self._written_metadata()))
        return path


def _names(declared: list[str] | None, letter: str, count: int) -> list[str]:
    """The header names of ``count`` channels: the declared ones, else ``u`` (one) or ``u1, u2, …``."""
    if declared is not None:
        if len(declared) != count:
            raise DataError(f"the metadata names {len(declared)} channel(s) {list(declared)} for the {count} columns of "
                            f"{letter!r}; name one per column, or drop the names")
        return list(declared)
    return [letter] if count == 1 else [f"{letter}{i}" for i in range(1, count + 1)]


def _column_names(declared: list[str] | None, letter: str, count: int) -> list[str]:
    """The channels' names where the metadata declares one per column, else ``u`` (one) or ``u1, u2, …``: what a
    message names a column by, before the names are checked (:func:`_names`)."""
    return _names(declared if declared is not None and len(declared) == count else None, letter, count)


def _has_outputs(header: list[str], metadata: dict, expected: tuple[Sequence[str], Sequence[str]] | None) -> bool:
    """Whether ``header`` holds any output column: those the metadata or ``expected`` names, ``y``, or ``y1, y2, …``."""
    named = set(metadata.get("outputs", [])) | set(expected[1] if expected else ())
    return any(h in named or re.fullmatch(r"y\d*", h) for h in header)


def _channels(header: list[str], metadata: dict, path: Path,
              expected: tuple[Sequence[str], Sequence[str]] | None = None) -> tuple[list[str], list[str]]:
    """The input and output columns of a CSV's ``header`` (:meth:`Record.from_csv`; ``expected``: the names a physics
    gives its channels); raises :class:`DataError` naming the columns that are missing and how to name them."""
    found = []
    for i, (letter, key) in enumerate((("u", "inputs"), ("y", "outputs"))):
        named = list(expected[i]) if expected is not None else []
        if key in metadata:
            names = list(metadata[key])
        elif letter in header:
            names = [letter]
        elif named and all(n in header for n in named):
            names = named
        else:
            names = sorted((h for h in header if re.fullmatch(rf"{letter}\d+", h)), key=lambda h: int(h[1:]))
        found.append(names or [letter])
    missing = [c for c in ["t", *found[0], *found[1]] if c not in header]
    if missing:
        rest = [h for h in header if h != "t"]
        example = json.dumps({"inputs": rest[:1], "outputs": rest[1:]})
        raise DataError(f"{path}: missing column(s) {missing}; the header is {header}, expected 't,u,y' or "
                        f"'t,u1,…,y1,…'; to keep your names, put a first line `# {example}` naming the input and "
                        "output columns (or name them in the physics' input_names and output_names)")
    return found[0], found[1]


def _as_columns(values, column: str) -> torch.Tensor:
    tensor = torch.as_tensor(values, dtype=torch.float64).detach()  # a record is data, never part of a graph
    if tensor.dim() == 1:
        return tensor[:, None]
    if tensor.dim() != 2:
        raise DataError(f"column {column!r} must be (time,) or (time, channel), got shape {tuple(tensor.shape)}")
    return tensor
