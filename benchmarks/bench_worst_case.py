"""The worst case a user meets: each library effect refitted on each library base, against the rung's own fit.

    python benchmarks/bench_worst_case.py [--lengths 4001 60001] [--out results/bench_worst_case.json]

Rungs: the oscillator, the pendulum and an oscillator with cubic stiffness, each without and with Coulomb friction
already on the rung (the demo's second rung). Records: the rung's own system with a hidden cubic damping
(-0.3 v^3: ``experiments/discovery/forces.py``, a force outside the library, so that every candidate has a residual to chase), pseudorandom training and
multisine validation, dt = 0.05 s, 2 % noise. For each rung: its fit (the baseline, timed in the same run), then each
of the twelve candidates refitted alone (``rank_missing_effects`` with that candidate, the first-order gate opened
so that the refit runs, within the default budget); the time is that of the refit (``refit_effect``), the rung's fit
and the scoring left out. A refit that the gate would not run is marked; one stopped by its budget is reported
undecided with its seconds. Last, discovery alone on a physics whose first-order form does
not hold (the pendulum with the hidden force, fitted by an oscillator), timed with its screening.

Reports, per length: the slowest refit against its rung's fit, the discovery's time, and the table of every refit.
One thread.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import sys
import time
from pathlib import Path

import torch

from torchpaml import (
    CoulombFriction,
    CubicStiffness,
    Oscillator,
    Pendulum,
    Simulated,
    default_effects,
    discover_missing_force,
    fit_physics,
    SelectionRule,
    rank_missing_effects,
)
from torchpaml._diagnostics import ranking as ranking_module

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "discovery"))
from forces import CubicDamping  # noqa: E402  (F = -c v^3)


def rungs() -> dict[str, torch.nn.Module]:
    """The rungs, every parameter of the physics learnable, at the true values."""
    bases = {
        "oscillator": lambda: Oscillator(zeta=0.2, omega0=2.0, gain=4.0),
        "pendulum": lambda: Pendulum(zeta=0.2, omega0=2.0, gain=2.0),
        "oscillator + cubic_stiffness": lambda: Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(2.0),
    }
    made = {}
    for name, base in bases.items():
        for coulomb in (False, True):
            model = base() + CoulombFriction(0.3) if coulomb else base()
            learn = [n for n in ("zeta", "omega0", "gain", "cubic_stiffness.k3", "coulomb_friction.Fc")
                     if n in model.physical_parameters()]
            made[name + (" + coulomb_friction" if coulomb else "")] = model.set_learnable(*learn)
    return made


def records(system, samples: int):
    truth = copy.deepcopy(system).set_learnable(*system.learnable_names(), learn=False) + CubicDamping(0.3)
    duration = (samples - 1) * 0.05
    return (Simulated(truth, "pseudorandom", 1.0, [0], duration, 0.05, noise=0.02).experiments(),
            Simulated(truth, "multisine", 1.0, [1], duration, 0.05, noise=0.02).experiments())


class _RefitTimer:
    """Times the refits of the ranking (``refit_effect``) while it is alive: the rung's fit and the scoring excluded."""

    def __init__(self):
        self.seconds, self.original = 0.0, ranking_module.refit_effect

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return self.original(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - start

        ranking_module.refit_effect = timed

    def stop(self):
        ranking_module.refit_effect = self.original


def refit_times(rung, train, validation) -> list[dict]:
    """Each library candidate refitted alone on ``rung``: seconds, outcome, whether the gate would refit it."""
    rows = []
    present = set(getattr(rung, "effects", {}))
    for effect in default_effects():
        if effect.name in present:
            continue
        original, ranking_module.GATE_MARGIN = ranking_module.GATE_MARGIN, math.inf  # open the gate: time the refit
        timer, start = _RefitTimer(), time.perf_counter()
        try:
            (entry,) = rank_missing_effects(rung, [copy.deepcopy(effect)], train, validation).entries
        finally:
            ranking_module.GATE_MARGIN = original
            timer.stop()
        seconds, whole = timer.seconds, time.perf_counter() - start
        extended = copy.deepcopy(rung) + copy.deepcopy(effect)
        would = ranking_module._cannot_pass(entry.score, SelectionRule(), validation, extended, rung) is None
        outcome = ("undecided" if entry.undecided is not None else "failed" if entry.failure else
                   "refitted" if entry.refit is not None else "not refitted")
        rows.append({"effect": effect.name, "seconds": seconds, "ranking_seconds": whole, "outcome": outcome,
                     "gate_refits": would, "score": entry.score})
        print(f"    {effect.name:20s} refit {seconds:7.2f} s (ranking {whole:7.2f} s)  {outcome:12s} "
              f"gate {'refits' if would else 'skips'}", flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="+", default=[4001, 60001])
    parser.add_argument("--rungs", nargs="+", default=None, help="only the rungs whose name contains one of these")
    parser.add_argument("--out", default="results/bench_worst_case.json")
    options = parser.parse_args()
    torch.set_num_threads(1)
    report = {"lengths": {}}
    for samples in options.lengths:
        print(f"{samples} samples", flush=True)
        cases = []
        for name, rung in rungs().items():
            if options.rungs and not any(part in name for part in options.rungs):
                continue
            train, validation = records(rung, samples)
            fit_physics(copy.deepcopy(rung), train)  # untimed: warms this rung's code paths up
            start = time.perf_counter()
            fit_physics(copy.deepcopy(rung), train)
            fit_seconds = time.perf_counter() - start
            print(f"  {name}: its fit {fit_seconds:.2f} s", flush=True)
            for row in refit_times(rung, train, validation):
                cases.append({"rung": name, "rung_fit": fit_seconds, **row, "ratio": row["seconds"] / fit_seconds})
        slowest = max(cases, key=lambda c: c["ratio"])
        train, validation = records(Pendulum(zeta=0.2, omega0=2.0, gain=2.0, learn=()), samples)  # + the hidden force
        start = time.perf_counter()
        base = rank_missing_effects(Oscillator(zeta=0.3, omega0=1.8, gain=1.5), [], train, validation)
        discovery = discover_missing_force(base, train, validation)
        discovery_seconds = time.perf_counter() - start
        report["lengths"][str(samples)] = {"refits": cases, "slowest": slowest, "discovery_seconds": discovery_seconds,
                                           "discovery": discovery.text}
        print(f"  slowest: {slowest['effect']} on {slowest['rung']}: {slowest['seconds']:.2f} s = "
              f"{slowest['ratio']:.1f} x its rung's fit ({slowest['outcome']})")
        print(f"  discovery alone (pendulum's truth, oscillator physics): {discovery_seconds:.1f} s, {discovery.text}")
    Path(options.out).parent.mkdir(parents=True, exist_ok=True)
    Path(options.out).write_text(json.dumps(report, indent=1))
    print(f"wrote {options.out}")


if __name__ == "__main__":
    main()
