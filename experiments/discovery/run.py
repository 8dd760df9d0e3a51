r"""Discovery on simulated records: four forces outside the library, one inside it, and none.

    python experiments/discovery/run.py --out DIR

Each case: the oscillator (zeta = 0.2, omega0 = 2 rad/s, g = 4) plus the hidden force generates a
pseudorandom training record and a multisine validation record (30 s at 20 Hz, 2 % output noise).
The diagnosed physics is the oscillator alone, started 25-75 % off. The library is ranked on it
(two refits), then :func:`~torchpaml._diagnostics.discover_missing_force` runs. The noise floor is
the validation mismatch of the noise-free record.

Writes ``DIR/discovery_cases.json`` (per case: the truth, ``discovery.json``'s content, the floor
and the seconds) and ``DIR/table.md``, the table of the docs' discovery pages.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch
from forces import OUTSIDE

from torchpaml import CoulombFriction, Oscillator, Simulated, default_effects, mismatch
from torchpaml.analysis import discover_missing_force, rank_missing_effects
from torchpaml.report import discovery_to_dict

NOISE = 0.02


def truth(effect=None):
    system = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=())
    return system if effect is None else system + effect


def physics():
    """The diagnosed physics: the oscillator alone, every parameter learnable, started 25-75 % off."""
    return Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain"))


def records(system):
    """([train], [validation], noise floor) of ``system``."""
    train = Simulated(system, "pseudorandom", 1.0, [0], 30.0, 0.05, noise=NOISE).experiments()[0]
    validation = Simulated(system, "multisine", 1.0, [1], 30.0, 0.05, noise=NOISE).experiments()[0]
    clean = Simulated(system, "multisine", 1.0, [1], 30.0, 0.05).experiments()[0]
    return [train], [validation], mismatch(validation.y, clean.y)


def discover(system, shortlist: int = 2):
    """(the discovery on ``system``'s records, the noise floor)."""
    train, validation, floor = records(system)
    ranking = rank_missing_effects(physics(), default_effects(), train, validation, shortlist=shortlist)
    return discover_missing_force(ranking, train, validation), floor


def cases() -> dict:
    """case -> (truth as text, system)."""
    table = {name: (f"{coefficient:g}*{term}", truth(make())) for name, (make, term, coefficient) in OUTSIDE.items()}
    table["coulomb_friction (library)"] = ("-0.5*tanh(v/0.01)", truth(CoulombFriction(0.5)))
    table["none"] = ("0", truth())
    return table


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(0)
    results = {}
    lines = ["| case | truth | discovered | recommended | library best | validation % physics / library / neural / "
             "discovered | floor % | s |", "|---|---|---|---|---|---|---|---|"]
    for name, (true, system) in cases().items():
        start = time.perf_counter()
        found, floor = discover(system)
        content = discovery_to_dict(found)
        seconds = time.perf_counter() - start
        results[name] = {"truth": true, "discovery": content, "floor": floor, "seconds": seconds}
        errors = " / ".join("—" if v is None else f"{100 * v:.2f}" for v in content["nrmse_validation"].values())
        lines.append(f"| {name} | `{true}` | `{content['expression']}` | {'yes' if content['recommended'] else 'no'} | "
                     f"{content['library_best']} | {errors} | {100 * floor:.2f} | {seconds:.0f} |")
        print(lines[-1], flush=True)
    (args.out / "discovery_cases.json").write_text(json.dumps(results, indent=2))
    (args.out / "table.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out / 'discovery_cases.json'} and {args.out / 'table.md'}")
    return results


if __name__ == "__main__":
    main()
