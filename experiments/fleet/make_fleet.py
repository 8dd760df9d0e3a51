"""A simulated fleet: units of one design with manufacturing spread, a few with a developed effect.

    python experiments/fleet/make_fleet.py --out DIR [--units 10] [--seed 0]

Every unit is the oscillator of the demo (ζ = 0.2, ω0 = 2 rad/s, g = 4) with each parameter spread
by its own manufacturing tolerance (ζ 5 %, ω0 2 %, g 3 %, normal, seeded). Some units have developed
an effect (:data:`DEVELOPED`: friction, a worn damper, a loose mount's offset), and one has an
outlying natural frequency (:data:`OUTLIER`). Each unit's folder holds ``train.csv`` (pseudorandom
input) and ``validation.csv`` (multisine), 30 s at 20 Hz with 2 % output noise, and ``DIR/truth.json``
records what each unit has: ``{unit: {parameters, effect}}``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch

from torchpaml import build_model, Simulated

#: unit index -> (library effect, strength) that unit has developed.
DEVELOPED = {2: ("coulomb_friction", 0.5), 5: ("quadratic_damping", 0.5), 7: ("constant_force", 0.5)}
#: unit index whose natural frequency is 20 % above the design's.
OUTLIER = 8
DESIGN = {"zeta": 0.2, "omega0": 2.0, "gain": 4.0}
TOLERANCE = {"zeta": 0.05, "omega0": 0.02, "gain": 0.03}
RECORDS = dict(amplitude=1.0, duration=30.0, dt=0.05, noise=0.02)


def make_fleet(out: Path, units: int = 10, seed: int = 0) -> dict:
    """Write the fleet into ``out`` (module docstring); returns the truth ``{unit: {parameters, effect}}``."""
    generator = torch.Generator().manual_seed(seed)
    truth = {}
    for i in range(units):
        name = f"unit{i:02d}"
        spread = torch.randn(len(DESIGN), generator=generator, dtype=torch.float64)
        parameters = {k: v * (1 + TOLERANCE[k] * float(z)) for (k, v), z in zip(DESIGN.items(), spread, strict=True)}
        if i == OUTLIER:
            parameters["omega0"] = 1.2 * DESIGN["omega0"]
        effect = DEVELOPED.get(i)
        model = build_model("oscillator", parameters, dict([effect]) if effect else None)
        folder = out / name
        folder.mkdir(parents=True, exist_ok=True)
        plan = (("pseudorandom", 2 * i, "train.csv"), ("multisine", 2 * i + 1, "validation.csv"))
        for signal, record_seed, file in plan:
            (record,) = Simulated(model, signal, seeds=[seed * 1000 + record_seed], **RECORDS).experiments()
            record.to_csv(folder / file)
        truth[name] = {"parameters": parameters, "effect": None if effect is None else effect[0]}
    (out / "truth.json").write_text(json.dumps(truth, indent=2))
    return truth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="the fleet's folder, one sub-folder per unit")
    parser.add_argument("--units", type=int, default=10, help="how many units (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the spread and the records")
    args = parser.parse_args()
    truth = make_fleet(args.out, args.units, args.seed)
    developed = {u: t["effect"] for u, t in truth.items() if t["effect"]}
    print(f"wrote {len(truth)} units into {args.out}; developed effects: {developed}")


if __name__ == "__main__":
    main()
