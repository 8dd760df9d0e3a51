"""The worst case a user meets: each library effect refitted on each library base, against the rung's own fit.

    python benchmarks/bench_worst_case.py [--lengths 4001 60001] [--rungs NAME ...] [--discovery-samples 25001]
                                          [--out results/bench_worst_case.json]

Rungs: the oscillator, the pendulum and an oscillator with cubic stiffness, each without and with Coulomb friction
already on the rung (the demo's second rung). Records: the rung's own system with a hidden cubic damping
(-0.3 v^3: ``experiments/discovery/forces.py``, a force outside the library, so that every candidate has a residual to chase), pseudorandom training and
multisine validation, dt = 0.05 s, 2 % noise. For each rung: its fit (the baseline, timed in the same run), then each
of the library candidates refitted alone (``rank_missing_effects`` with that candidate, the first-order gate opened
so that the refit runs, within the default budget); the time is that of the refit (``refit_effect``), the rung's fit
and the scoring left out. A refit that the gate would not run is marked; one stopped by its budget is reported
undecided with its seconds. Last, discovery alone on a physics whose first-order form does
not hold (the pendulum with the hidden force, fitted by an oscillator), timed with its screening.

Reports, per length, the slowest refit against its rung's fit and the table of every refit; then the discovery's
time and the terms it screened. One thread. ``--out`` collects runs: a run replaces the rows of the rungs and lengths
it ran and keeps the others (``make tables`` renders the file on the benchmarks page).

``--cases`` adds whole runs a user meets (``bounded`` in the file):

* ``memory_rung``: the rung after an effect with memory under a sharp sign (an oscillator with LuGre friction,
  sigma0 = 400, zc = 1e-3, 1 201 samples): the refit that finds it, the next rung's fit from its optimum within its
  budget (ten times the refit), and the same fit unbounded (``fit_budget`` infinite), the time it would take;
* ``pendulum``: a pendulum with cubic damping (c = 0.3, 4 001 samples), ``diagnose`` with the discovery, whole;
* ``two_output``: the two-mass chain of ``tests/two_mass.py`` (Coulomb friction on the second mass, both positions
  measured, 12 001 samples), ``diagnose`` with the discovery, whole; and its discovery asked to go on
  (``Discoverer(always=True)``) on the complete final model, the slowest path.
"""

from __future__ import annotations

import argparse
import copy
import json
import logging
import math
import sys
import time
from pathlib import Path

import torch

from torchpaml import (
    CoulombFriction,
    CubicStiffness,
    Discoverer,
    DynamicFriction,
    Oscillator,
    Pendulum,
    Ranker,
    SelectionRule,
    Simulated,
    build_model,
    default_effects,
    diagnose,
    fit_physics,
)
from torchpaml.analysis import discover_missing_force, model_ladder, rank_missing_effects
from torchpaml._diagnostics.ranking import refits as refits_module

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "discovery"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from forces import CubicDamping  # noqa: E402  (F = -c v^3)
from two_mass import FRICTION, TRUTH, TwoMass  # noqa: E402  (a user's physics with two outputs)


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
    """The rung's own system with the hidden cubic damping, measured (:func:`measured`)."""
    return measured(copy.deepcopy(system).set_learnable(*system.learnable_names(), learn=False) + CubicDamping(0.3),
                    samples)


def measured(device, samples: int):
    """Pseudorandom training and multisine validation records of ``device`` as it is, at 20 Hz with 2 % noise."""
    duration = (samples - 1) * 0.05
    return (Simulated(device, "pseudorandom", 1.0, [0], duration, 0.05, noise=0.02).experiments(),
            Simulated(device, "multisine", 1.0, [1], duration, 0.05, noise=0.02).experiments())


class _RefitTimer:
    """Times the refits of the ranking (``refit_effect``) while it is alive: the rung's fit and the scoring excluded."""

    def __init__(self):
        self.seconds, self.original = 0.0, refits_module.refit_effect

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return self.original(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - start

        refits_module.refit_effect = timed

    def stop(self):
        refits_module.refit_effect = self.original


def refit_times(rung, train, validation) -> list[dict]:
    """Each library candidate refitted alone on ``rung``: seconds, outcome, whether the gate would refit it."""
    rows = []
    present = set(getattr(rung, "effects", {}))
    for effect in default_effects():
        if effect.name in present:
            continue
        original, refits_module.GATE_MARGIN = refits_module.GATE_MARGIN, math.inf  # open the gate: time the refit
        timer, start = _RefitTimer(), time.perf_counter()
        try:
            (entry,) = rank_missing_effects(rung, [copy.deepcopy(effect)], train, validation).entries
        finally:
            refits_module.GATE_MARGIN = original
            timer.stop()
        seconds, whole = timer.seconds, time.perf_counter() - start
        extended = copy.deepcopy(rung) + copy.deepcopy(effect)
        would = refits_module.cannot_pass(entry.score, SelectionRule(), validation, extended, rung) is None
        outcome = ("undecided" if entry.undecided is not None else "failed" if entry.failure else
                   "refitted" if entry.refit is not None else "not refitted")
        rows.append({"effect": effect.name, "seconds": seconds, "ranking_seconds": whole, "outcome": outcome,
                     "gate_refits": would, "score": entry.score})
        print(f"    {effect.name:20s} refit {seconds:7.2f} s (ranking {whole:7.2f} s)  {outcome:12s} "
              f"gate {'refits' if would else 'skips'}", flush=True)
    return rows


class _Screens(logging.Handler):
    """Counts the discovery's screened terms (its progress lines)."""

    def __init__(self):
        super().__init__()
        self.count = 0

    def emit(self, record):
        self.count += record.getMessage().startswith("discovery: screening ") and " of " in record.getMessage()


def discovery_case(samples: int) -> dict:
    """Discovery on the last rung of the pendulum's ladder (the pendulum with the hidden force, diagnosed from a
    pendulum with every parameter learnable): Pendulum + quadratic_damping + coulomb_friction, whose fit the records
    do not determine along one direction, so the first-order form may be misled and the search by refits runs."""
    train, validation = records(Pendulum(zeta=0.2, omega0=2.0, gain=2.0, learn=()), samples)
    start = Pendulum(zeta=0.4, omega0=1.6, gain=1.5, learn=("zeta", "omega0", "gain"))
    ladder = model_ladder(start, default_effects(), train, validation)
    screens, logger = _Screens(), logging.getLogger("torchpaml")  # the search logs from closed_form_search
    logger.addHandler(screens)
    level, logger.level = logger.level, logging.INFO
    began = time.perf_counter()
    try:
        found = discover_missing_force(ladder.rankings[-1], train, validation)
    finally:
        logger.removeHandler(screens)
        logger.setLevel(level)
    seconds = time.perf_counter() - began
    print(f"discovery on {ladder.final.name} ({samples} samples): {seconds:.1f} s, {screens.count} terms screened, "
          f"{found.text}; undecided: {found.undecided or 'none'}", flush=True)
    return {"samples": samples, "rung": ladder.final.name, "seconds": seconds, "screened": screens.count,
            "discovery": found.text, "undecided": found.undecided}


def memory_rung_case(samples: int = 1201) -> dict:
    """The rung after LuGre friction under a sharp sign (module docstring): its refit, its fit within its budget, and
    the same fit unbounded."""
    device = build_model("oscillator", {"zeta": 0.2, "gain": 4.0}) + DynamicFriction(sigma0=400.0, zc=1e-3)
    train, validation = measured(device, samples)
    rows = {}
    for label, ranker in (("bounded", Ranker()), ("unbounded", Ranker(fit_budget=1e9))):
        physics = build_model("oscillator").set_learnable("zeta", "omega0", "gain")
        ladder = model_ladder(physics, [DynamicFriction()], train, validation, ranker=ranker)
        refit, rung = ladder.rankings[0].recommended, ladder.rankings[1]
        rows[label] = {"refit": refit.seconds, "rung_fit": rung.fit_seconds - refit.seconds,
                       "stopped": rung.fit_over_budget is not None, "nrmse_validation": ladder.final.nrmse_validation}
        print(f"  memory rung, {label}: refit {refit.seconds:.2f} s, the rung's fit {rows[label]['rung_fit']:.2f} s "
              f"({'stopped over its budget' if rows[label]['stopped'] else 'ended'}), validation "
              f"{100 * ladder.final.nrmse_validation:.2f} %", flush=True)
    return {"samples": samples, **rows}


def _diagnosis_seconds(name: str, physics, candidates, train, validation, discovery) -> dict:
    """One whole ``diagnose``, timed, with what it found."""
    began = time.perf_counter()
    diagnosis = diagnose(physics, candidates, train, validation, discovery=discovery)
    seconds = time.perf_counter() - began
    found = diagnosis.discovery
    row = {"seconds": seconds, "added": diagnosis.ladder.added,
           "nrmse_validation": diagnosis.ladder.final.nrmse_validation,
           "discovery": None if found is None else found.text, "searched": None if found is None else found.searched}
    print(f"  {name}: {seconds:.1f} s, added {row['added']}, validation {100 * row['nrmse_validation']:.2f} %, "
          f"discovery {row['discovery']!r} (searched: {row['searched']})", flush=True)
    return row


def pendulum_case(samples: int = 4001) -> dict:
    """A pendulum with cubic damping, ``diagnose`` with the discovery (module docstring)."""
    truth = Pendulum(zeta=0.2, omega0=2.0, gain=2.0, learn=()) + CubicDamping(0.3)
    train, validation = measured(truth, samples)
    physics = Pendulum(learn=("zeta", "omega0", "gain"))
    return {"samples": samples, **_diagnosis_seconds("pendulum with --discover", physics, default_effects(), train,
                                                     validation, Discoverer())}


def two_output_case(samples: int = 12001) -> dict:
    """The two-mass chain, ``diagnose`` with the discovery; then the discovery asked to go on (module docstring)."""
    device = TwoMass(**TRUTH, learn=()) + CoulombFriction(FRICTION).on("v2")
    train, validation = measured(device, samples)
    rows = {name: _diagnosis_seconds(f"two-mass chain, {name}", TwoMass(), default_effects(), train, validation,
                                     Discoverer(always=always))
            for name, always in (("discover", False), ("discover_always", True))}
    return {"samples": samples, **rows}


CASES = {"memory_rung": memory_rung_case, "pendulum": pendulum_case, "two_output": two_output_case}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="*", default=[4001, 60001], help="record lengths (none: the discovery alone)")
    parser.add_argument("--rungs", nargs="+", default=None, help="only the rungs whose name contains one of these")
    parser.add_argument("--discovery-samples", type=int, default=25001, help="the discovery case's length (0: none)")
    parser.add_argument("--cases", nargs="*", default=[], choices=sorted(CASES), help="whole runs (module docstring)")
    parser.add_argument("--out", default="results/bench_worst_case.json")
    options = parser.parse_args()
    torch.set_num_threads(1)
    out = Path(options.out)
    report = json.loads(out.read_text()) if out.is_file() else {"lengths": {}}  # a run adds to, or replaces, its rows
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
        kept = [c for c in report["lengths"].get(str(samples), {}).get("refits", []) if c["rung"] not in
                {case["rung"] for case in cases}]
        cases = kept + cases
        slowest = max(cases, key=lambda c: c["ratio"])
        report["lengths"][str(samples)] = {"refits": cases, "slowest": slowest}
        print(f"  slowest: {slowest['effect']} on {slowest['rung']}: {slowest['seconds']:.2f} s = "
              f"{slowest['ratio']:.1f} x its rung's fit ({slowest['outcome']})", flush=True)
    if options.discovery_samples:
        report["discovery"] = discovery_case(options.discovery_samples)
    for case in options.cases:
        print(case, flush=True)
        report.setdefault("bounded", {})[case] = CASES[case]()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=1))
    print(f"wrote {options.out}")


if __name__ == "__main__":
    main()
