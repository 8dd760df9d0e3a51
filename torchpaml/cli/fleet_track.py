"""``torchpaml track --units DIR --out OUT``: every unit of a fleet tracked on its own model, on Ray.

Each unit folder of ``DIR`` holds its saved model (``model.pt``, as ``torchpaml fleet`` or ``torchpaml diagnose``
writes it) and its stream (``stream.csv``: t, the model's inputs and outputs; an empty or NaN output cell is a
missing measurement). One Ray task per unit runs what ``torchpaml track`` runs on one (:func:`track_unit`) and
writes ``OUT/<unit>/track.json`` and ``track.png``; the fleet's table, which units changed and the parameter each
alarm names, goes to ``OUT/fleet_track.json`` and ``OUT/fleet_track.md``. The tracking options (``--window``,
``--alpha``, ``--attribution``, ``--process-noise``, ``--hold``, ``--trust``) apply to every unit; ``--noise`` and
``--x0`` are per device and are refused here. A unit whose model or stream is refused gets its ``error`` and the
fleet goes on. Without ``--address`` a local Ray is started on ``--workers`` cores and stopped at the end.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

from torchpaml._errors import TorchpamlError

__all__ = ["FLEET_TRACK_FILE", "fleet_table", "track_fleet", "track_unit"]

log = logging.getLogger(__name__)

FLEET_TRACK_FILE = "fleet_track.json"
#: What each unit folder holds.
UNIT_FILES = ("model.pt", "stream.csv")


def track_unit(folder: str, out: str, options: dict, trust: tuple[str, ...], threads: int = 1) -> dict:
    """Track one unit (module docstring) into ``out/<unit>``; its row of the fleet's table:
    ``{unit, changed, alarms: [{t, parameter}], samples, missing_samples, seconds, error}``."""
    import torch

    from torchpaml._data import Record
    from torchpaml._model import load_model
    from torchpaml._render.tracking import write_tracking
    from torchpaml._track import track

    torch.set_num_threads(threads)
    folder = Path(folder)
    row = {"unit": folder.name, "changed": None, "alarms": [], "samples": 0, "missing_samples": 0, "seconds": 0.0,
           "error": None}
    started = time.perf_counter()
    try:
        model = load_model(folder / UNIT_FILES[0], trust=trust)
        record = Record.from_csv(folder / UNIT_FILES[1], channels=(model.inputs, model.outputs), hold=options.get("hold"),
                                 missing_outputs=True)
        tracking = track(model, record, **{k: v for k, v in options.items() if v is not None})
        write_tracking(tracking, Path(out) / folder.name)
    except TorchpamlError as error:
        row["error"] = str(error)
        return row
    row.update(changed=bool(tracking.alarms), samples=len(tracking.t), missing_samples=tracking.missing,
               alarms=[{"t": a.t, "parameter": a.parameter} for a in tracking.alarms],
               seconds=time.perf_counter() - started)
    return row


def fleet_table(rows: list[dict]) -> str:
    """The fleet's table as Markdown: each unit, whether it changed, its first alarm and the parameter named."""
    lines = ["| unit | changed | first alarm (s) | parameter that moved | alarms | samples (missing) |",
             "|---|---|---|---|---|---|"]
    for row in rows:
        if row["error"] is not None:
            lines.append(f"| {row['unit']} | error: {row['error']} | | | | |")
            continue
        first = row["alarms"][0] if row["alarms"] else None
        lines.append(f"| {row['unit']} | {'yes' if row['changed'] else 'no'} | "
                     f"{'' if first is None else format(first['t'], '.4g')} | "
                     f"{'' if first is None else first['parameter'] or 'undetermined'} | {len(row['alarms'])} | "
                     f"{row['samples']} ({row['missing_samples']}) |")
    return "\n".join(lines) + "\n"


def track_fleet(units: Path, out: Path, options: dict, trust: tuple[str, ...], *, address: str | None = None,
                workers: int = 2) -> dict:
    """Track every unit on Ray (module docstring); returns the content of ``fleet_track.json``:
    ``{schema_version, engine, workers, seconds, units: [row of track_unit]}``."""
    from torchpaml.cli.fleet import find_units, ray_module, thread_environment, worker_threads

    folders = find_units(units, " and ".join(UNIT_FILES))
    out.mkdir(parents=True, exist_ok=True)
    ray = ray_module()
    start = time.perf_counter()
    threads = worker_threads(workers)
    with thread_environment(threads):
        ray.init(address=address, num_cpus=None if address else workers, include_dashboard=False,
                 log_to_driver=False, logging_level=logging.ERROR)
    try:
        task = ray.remote(num_cpus=1)(track_unit)
        pending = {task.remote(str(f), str(out), options, trust, threads): f.name for f in folders}
        rows = {}
        while pending:
            (ready,), _ = ray.wait(list(pending), num_returns=1)
            name = pending.pop(ready)
            rows[name] = ray.get(ready)
            log.info("tracked %s: %d of %d units (%.0f s)", name, len(rows), len(folders), time.perf_counter() - start)
    finally:
        ray.shutdown()
    fleet = {"schema_version": 1, "engine": "ray", "workers": workers, "seconds": time.perf_counter() - start,
             "units": [rows[f.name] for f in folders]}
    (out / FLEET_TRACK_FILE).write_text(json.dumps(fleet, indent=2))
    (out / "fleet_track.md").write_text(fleet_table(fleet["units"]))
    return fleet
