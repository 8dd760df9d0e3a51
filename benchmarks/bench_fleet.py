"""A fleet on a local Ray: its wall time against the sum of its units' own seconds, in one run.

    python benchmarks/bench_fleet.py [--units 10] [--workers 2]

Generates the fleet of ``experiments/fleet/make_fleet.py`` in a temporary folder and diagnoses it with
``torchpaml fleet`` (every library effect a candidate). Each unit's task measures its own seconds; the
sum is what one process would take for the units one after another. Prints the fleet's wall time, the
sum, the speed-up (sum / wall), and where the rest goes: Ray's start-up (``ray.init``), the workers'
own start (process and imports, until the first unit begins), and the efficiency while the units run
(their seconds over workers x the span from the first unit's start to the last one's end).
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "fleet"))
from make_fleet import make_fleet  # noqa: E402  (the experiment's generator, beside it in the repository)

from torchpaml.cli.fleet import diagnose_fleet  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--units", type=int, default=10, help="units in the fleet (default 10)")
    parser.add_argument("--workers", type=int, default=2, help="cores of the local Ray (default 2)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        units = Path(folder) / "units"
        make_fleet(units, args.units)
        start = time.time()
        fleet = diagnose_fleet(units, Path(folder) / "out", {"physics": "oscillator"}, workers=args.workers,
                               progress=sys.stderr.isatty())
        ends = {row["unit"]: (Path(folder) / "out" / row["unit"] / "unit.json").stat().st_mtime - start
                for row in fleet["units"]}
    own = sum(row["seconds"] for row in fleet["units"])
    first = min(ends[row["unit"]] - row["seconds"] for row in fleet["units"])
    span = max(ends.values()) - first
    failed = [row["unit"] for row in fleet["units"] if row["error"]]
    print(f"{len(fleet['units'])} units on {fleet['workers']} workers (failed: {failed or 'none'})")
    print(f"fleet wall time:              {fleet['seconds']:7.1f} s")
    print(f"sum of the units' own times:  {own:7.1f} s  (one process, one unit after another)")
    print(f"speed-up:                     {own / fleet['seconds']:7.2f} x on {fleet['workers']} workers")
    print(f"Ray start-up (ray.init):      {fleet['startup_seconds']:7.1f} s")
    print(f"workers' start and imports:   {first - fleet['startup_seconds']:7.1f} s, until the first unit begins")
    print(f"while the units run:          {own / (fleet['workers'] * span):7.0%} of {fleet['workers']} workers busy "
          f"({span:.1f} s)")

if __name__ == "__main__":
    main()
