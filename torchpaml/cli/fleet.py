"""``torchpaml fleet``: diagnose many units of one design on Ray, and see which ones changed.

``torchpaml fleet --units DIR --physics NAME --out OUT [--address ADDR] [--workers N]`` diagnoses every
unit folder of ``DIR`` (each with ``train.csv`` and ``validation.csv``) as ``torchpaml diagnose``
would, one Ray task per unit, and writes ``OUT/<unit>/`` (each unit's diagnosis), ``OUT/fleet.json``
and ``OUT/fleet.html``. The diagnose options (``--fix``, ``--effect``, ``--shortlist``, ``--hold``,
``--initial_state``, ``--discover``, ``--config`` ...) apply to every unit. Without ``--address`` a
local Ray is started on ``--workers`` cores and stopped at the end; with it the command joins a
running cluster. A rerun into the same ``OUT`` skips the units already diagnosed without error
(``--force`` redoes them); Ctrl-C stops the workers and keeps the finished units.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import sys
import time
from pathlib import Path

import yaml

from torchpaml._diagnostics.analysis.spread import fleet_spread
from torchpaml._errors import ConfigurationError, DataError
from torchpaml._render.fleet import write_fleet_report
from torchpaml.cli.diagnose import SWITCHES, check_options, diagnose_parser, normalise_arguments, resolve_models
from torchpaml.cli.fleet_unit import diagnose_unit, finished

__all__ = ["FLEET_FILE", "THREAD_VARIABLES", "diagnose_fleet", "find_units", "ray_module", "run_fleet", "thread_environment",
           "worker_threads"]

log = logging.getLogger(__name__)

#: The environment variables that set the threads of the BLAS and OpenMP pools in each Ray worker.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

FLEET_FILE = "fleet.json"
#: The arguments of the fleet itself; every other argument is the diagnose command's, for every unit.
FLEET_ARGUMENTS = ("units", "out", "address", "workers", "force", "quiet")


def ray_module():
    try:
        import ray
    except ImportError:
        raise ConfigurationError("torchpaml fleet runs its units on Ray, which is not installed; install the extra: "
                         "pip install 'torchpaml[fleet]'") from None
    return ray


def worker_threads(workers: int) -> int:
    """Threads of each worker's torch and BLAS, so that workers x threads <= the machine's cores: on two cores, two
    workers of two threads each ran a unit up to 7x slower than one thread alone."""
    return max(1, (os.cpu_count() or 1) // max(1, workers))


@contextlib.contextmanager
def thread_environment(threads: int):
    """:data:`THREAD_VARIABLES` set to ``threads`` while the block runs (the processes it starts inherit them), then
    restored."""
    before = {name: os.environ.get(name) for name in THREAD_VARIABLES}
    os.environ.update({name: str(threads) for name in THREAD_VARIABLES})
    try:
        yield
    finally:
        for name, value in before.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def find_units(folder: Path, holding: str = "train.csv and validation.csv") -> list[Path]:
    """Every sub-folder of ``folder`` (hidden ones aside) is a unit, in name order; ``holding`` names what each unit
    folder holds, in the refusals."""
    if not folder.is_dir():
        raise DataError(f"--units {folder} is not a folder; give a folder with one sub-folder per unit, each holding "
                        f"{holding}")
    units = sorted(p for p in folder.iterdir() if p.is_dir() and not p.name.startswith("."))
    if not units:
        raise DataError(f"--units {folder} has no unit folders; put one folder per unit in it, each holding {holding}")
    return units


def diagnose_fleet(units: Path, out: Path, options: dict, *, address: str | None = None, workers: int = 2,
                   force: bool = False, progress: bool = True) -> dict:
    """Diagnose every unit on Ray (module docstring); returns the content of ``fleet.json``.

    Args:
        units: the folder of unit folders.
        out: the output folder.
        options: the diagnose command's arguments as plain data (physics by name or ``class_path``).
        address: a running Ray cluster to join; default a local Ray on ``workers`` cores.
        workers: cores of the local Ray (each unit's task takes one).
        force: diagnose every unit, also those already diagnosed into ``out``.
        progress: show a progress bar over the units.
    """
    from tqdm import tqdm

    folders = find_units(units)
    out.mkdir(parents=True, exist_ok=True)
    rows = {} if force else {f.name: row for f in folders if (row := finished(out, f.name)) is not None}
    skipped = sorted(rows)
    todo = [f for f in folders if f.name not in rows]
    ray = ray_module()
    start = time.perf_counter()
    startup = 0.0
    if todo:
        threads = worker_threads(workers)
        with thread_environment(threads):  # the local workers inherit it (a runtime_env costs 0.5 s of their start)
            ray.init(address=address, num_cpus=None if address else workers, include_dashboard=False,
                     log_to_driver=False, logging_level=logging.ERROR)
        startup = time.perf_counter() - start
        workers = int(ray.cluster_resources().get("CPU", workers)) if address else workers
        task = ray.remote(num_cpus=1)(diagnose_unit)
        pending = {task.remote(str(f), str(out), options, threads): f.name for f in todo}
        bar = tqdm(total=len(folders), initial=len(rows), unit="unit", desc="fleet", disable=not progress)
        failed = 0
        try:
            while pending:
                (ready,), _ = ray.wait(list(pending), num_returns=1)
                name = pending.pop(ready)
                rows[name] = ray.get(ready)
                failed += rows[name]["error"] is not None
                bar.set_postfix(done=len(rows) - failed, failed=failed, left=len(pending))
                bar.update()
        finally:  # on Ctrl-C too: shutting Ray down stops its workers; a unit that finishes meanwhile is whole
            # (its folder is written atomically). No ray.cancel(force=True): a task that completes while it is
            # cancelled crashes Ray's core worker ("Tried to complete task that was not pending", Ray 2.x).
            bar.close()
            ray.shutdown()
    seconds = time.perf_counter() - start
    work = sum(rows[f.name]["seconds"] for f in folders if f.name not in skipped)
    fleet = {"schema_version": 1, "engine": "ray", "workers": workers, "seconds": seconds,
             "startup_seconds": startup, "unit_seconds": work, "skipped": skipped,
             "units": [rows[f.name] for f in folders]}
    log.info("fleet: %d unit(s) in %.1f s of wall time for %.1f s of the units' own work (%.2fx on %d workers)",
             len(todo), seconds, work, work / seconds if seconds > 0 else 0.0, workers)
    path = out / FLEET_FILE
    path.with_suffix(".json.partial").write_text(json.dumps(fleet, indent=2))
    os.replace(path.with_suffix(".json.partial"), path)
    write_fleet_report(fleet, fleet_spread(fleet), out)
    return fleet


def fleet_parser(prog: str = "torchpaml fleet"):
    """The diagnose command's parser without its records and output, plus the fleet's own arguments."""
    parser = diagnose_parser(prog, skip={"data", "validation", "out", "quiet"})
    parser.description = __doc__
    parser.add_argument("--units", required=True, help="folder with one sub-folder per unit, each holding train.csv "
                                                       "and validation.csv")
    parser.add_argument("--out", required=True, help="output folder: OUT/<unit>/, fleet.json, fleet.html")
    parser.add_argument("--address", default=None, help="a running Ray cluster to join (e.g. HOST:6379); default "
                                                        "a local Ray, started and stopped by the command")
    parser.add_argument("--workers", type=int, default=2, help="cores of the local Ray, one unit each (default 2)")
    parser.add_argument("--force", type=bool, default=False, help="diagnose again the units already in OUT")
    parser.add_argument("--quiet", type=bool, default=False, help="no progress bar")
    return parser


def run_fleet(argv: list[str], prog: str = "torchpaml fleet") -> dict:
    """Parse ``argv`` (after ``fleet``), check every option before any work, and run :func:`diagnose_fleet`."""
    parser = fleet_parser(prog)
    config = parser.parse_args(normalise_arguments(argv, (*SWITCHES, "--force", "--quiet")))
    plain = yaml.safe_load(parser.dump(config))
    plain.pop("config", None)
    fleet = {name: plain.pop(name, None) for name in FLEET_ARGUMENTS}
    checked = parser.instantiate(config)
    check_options(checked.shortlist, checked.min_share, checked.refit_budget, checked.budget, checked.beam)
    resolve_models(checked.physics, checked.fix, checked.effects, checked.candidates, checked.discover)
    if fleet["workers"] < 1:
        raise ConfigurationError(f"--workers must be at least 1, got {fleet['workers']}")
    out = Path(fleet["out"])
    if out.is_file():
        raise ConfigurationError(f"--out {out} is an existing file; name a folder for the fleet (it is created if missing)")
    try:
        result = diagnose_fleet(Path(fleet["units"]), out, plain, address=fleet["address"], workers=fleet["workers"],
                                force=bool(fleet["force"]), progress=not fleet["quiet"])
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; the finished units are kept in {out}: run the same command to resume",
              file=sys.stderr)
        raise SystemExit(130) from None
    failed = [row["unit"] for row in result["units"] if row["error"] is not None]
    changed = {row["unit"]: row["found"] for row in result["units"] if row["found"]}
    print(f"{len(result['units'])} units in {result['seconds']:.0f} s ({len(result['skipped'])} already done); "
          f"missing effects: {changed or 'none'}; failed: {failed or 'none'}")
    print(f"wrote {out / FLEET_FILE}, {out / 'fleet.html'} and one folder per unit")
    return result
