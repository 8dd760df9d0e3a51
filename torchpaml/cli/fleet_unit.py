"""One unit of ``torchpaml fleet``: the single-unit diagnosis into a staging folder, put in place in one rename.

A unit is a folder with ``train.csv`` and ``validation.csv``, or several of each: every ``train*.csv`` (``train.csv``,
``train_2.csv``, ...) is a training record and every ``validation*.csv`` a validation record (:func:`unit_records`),
each with its own length and initial state. Its task runs :func:`diagnose_command`,
the same as ``torchpaml diagnose``, with the fleet's options, into ``OUT/.<unit>.partial``; writes
``unit.json`` there (:func:`summary`); and renames the folder to ``OUT/<unit>``. So ``OUT/<unit>``
holds either a whole result or nothing, and ``unit.json`` marks a unit that was run. A unit whose
records are bad, or whose diagnosis fails, gets its ``error``; the fleet goes on.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import time
import warnings
from pathlib import Path

__all__ = ["RECORDS", "UNIT_FILE", "diagnose_unit", "finished", "summary", "unit_records"]

UNIT_FILE = "unit.json"
#: A unit's first training and validation record; more are ``train*.csv`` and ``validation*.csv`` beside them.
RECORDS = ("train.csv", "validation.csv")


def unit_records(folder: str | Path) -> dict[str, list[str]]:
    """``{"data": [...], "validation": [...]}``: the unit's ``train*.csv`` and ``validation*.csv`` files, sorted by
    name (``train.csv`` first); a missing ``train.csv`` or ``validation.csv`` stays named, so that its error says
    which file is missing."""
    folder = Path(folder)
    found = {}
    for key, first in zip(("data", "validation"), RECORDS, strict=True):
        stem = first.removesuffix(".csv")
        more = sorted(str(p) for p in folder.glob(f"{stem}*.csv") if p.name != first)
        found[key] = [str(folder / first), *more]
    return found


def summary(unit: str, content: dict | None, seconds: float, error: str | None = None) -> dict:
    """A unit's row of ``fleet.json`` from its ``diagnosis.json`` ``content`` (``None`` when it failed).

    ``found``: the effects the ladder added, in order; ``nrmse_validation``: the physics' and the final
    model's validation mismatch; ``parameters`` and ``uncertainty``: the final model's.
    """
    if content is None:
        return {"unit": unit, "found": [], "nrmse_validation": {"baseline": None, "final": None}, "parameters": {},
                "uncertainty": {}, "seconds": seconds, "error": error}
    final = content["ladder"][-1]
    return {"unit": unit, "found": [rung["added"] for rung in content["ladder"][1:]],
            "nrmse_validation": {"baseline": content["baseline"]["nrmse_validation"],
                                 "final": final["nrmse_validation"]},
            "parameters": final["parameters"], "uncertainty": final["uncertainty"], "seconds": seconds, "error": None}


def finished(out: Path, unit: str) -> dict | None:
    """The unit's summary if it was diagnosed without error into ``out``, else ``None`` (to run it again)."""
    path = out / unit / UNIT_FILE
    if not path.is_file():
        return None
    row = json.loads(path.read_text())
    return row if row.get("error") is None else None


def diagnose_unit(folder: str, out: str, options: dict, threads: int = 1) -> dict:
    """Diagnose one unit (module docstring) with ``options``, the diagnose command's arguments as plain data
    (physics by name or ``class_path``), on ``threads`` threads of torch (the fleet gives each worker its share of
    the cores); returns its summary."""
    import torch

    from torchpaml.cli.diagnose import diagnose_command, diagnose_parser

    torch.set_num_threads(threads)
    unit, out = Path(folder).name, Path(out)
    staging, target = out / f".{unit}.partial", out / unit
    shutil.rmtree(staging, ignore_errors=True)
    start = time.perf_counter()
    try:
        parser = diagnose_parser()
        config = parser.instantiate(parser.parse_object({**options, **unit_records(folder), "out": str(staging)}))
        del config["config"]
        with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            content = diagnose_command(**config)
        row = summary(unit, content, time.perf_counter() - start)
    except Exception as err:  # noqa: BLE001 - a unit's failure is its result, and the fleet goes on
        row = summary(unit, None, time.perf_counter() - start, f"{type(err).__name__}: {err}")
    staging.mkdir(parents=True, exist_ok=True)
    (staging / UNIT_FILE).write_text(json.dumps(row, indent=2))
    shutil.rmtree(target, ignore_errors=True)
    os.replace(staging, target)
    return row
