"""The same records give the same answer on another machine: each diagnosis rerun along the paths a machine can change.

    python benchmarks/bench_same_answer.py [--samples 1200] [--cases demo cubic_stiffness quadratic_damping
                                           cascaded_tanks emps boucwen silverbox]
                                           [--out results/bench_same_answer.json]

A test on one machine cannot see another machine; this emulates what can differ. Each case is diagnosed (the
nineteen library effects, the default settings) four times:

* **reference**: as the machine runs it (two threads, the compiled path);
* **1 thread**: torch's and the BLAS pools held at one thread for the whole diagnosis;
* **engine**: the compiled path switched off (as on a machine without a C compiler): every simulation and Jacobian
  in the torch engine, whose Jacobian is a central difference, and linear recurrences by the scan;
* **perturbed**: the records' inputs and outputs multiplied by ``1 + 1e-12 s`` (s a random sign per sample), the
  rounding of another machine's CSV writer or sensor chain.

Compared with the reference: the decisions (the effects the ladder added, in order, and the probes' first place) must
agree; the figures (each rung's physics and hybrid mismatch on training and validation) are reported as the largest
relative difference, of all of them and of the physics' alone, with the goal 1e-6. Cases: records of the demo's oscillator (20 Hz, 2 % noise, pseudorandom
training, multisine validation) with one hidden library effect each; and the four measured benchmarks
(``cascaded_tanks``, ``emps``, ``boucwen``, ``silverbox``), each as ``make leaderboard`` diagnoses it (its
experiment's ``diagnosed``: the user's physics and effects; its discovery and hypotheses aside), on one thread and on
perturbed records only: through the engine the tanks' kinked fits take about 1 000 s. Each needs its folder of
``../shared/data`` and is left out where that is absent.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib.util
import json
import sys
import time
import warnings
from pathlib import Path

import torch

from torchpaml import (CompiledPathWarning, CoulombFriction, CubicStiffness, Oscillator, QuadraticDamping, Record,
                       Simulated, default_effects, diagnose)
from torchpaml._fit.one_thread import one_thread
from torchpaml.leaderboard import benchmark
from torchpaml._simulate import compiled, scan

CASES = {"demo": CoulombFriction(0.5), "cubic_stiffness": CubicStiffness(3.0), "quadratic_damping": QuadraticDamping(0.8)}
#: The measured benchmarks, diagnosed by their experiments' own ``diagnosed`` (as ``make leaderboard`` does).
BENCHMARKS = ("cascaded_tanks", "emps", "boucwen", "silverbox")
DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
GOAL = 1e-6


def available(case: str) -> bool:
    return case in CASES or (DATA / benchmark(case).folder / f"{benchmark(case).train}.csv").is_file()


def records(case: str, samples: int) -> tuple[list[Record], list[Record]]:
    if case in BENCHMARKS:
        protocol = benchmark(case)
        path = DATA / protocol.folder / f"{protocol.train}.csv"
        train, validation = protocol.split(Record.from_csv(path, protocol.train, hold=protocol.hold))
        return [train], [validation]
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CASES[case]
    settings = dict(amplitude=1.0, duration=samples * 0.05, dt=0.05, noise=0.02)
    return (Simulated(truth, "pseudorandom", seeds=[0], **settings).experiments(),
            Simulated(truth, "multisine", seeds=[1], **settings).experiments())


@functools.cache
def experiment(case: str):
    """``experiments/<case>/run.py`` as a module of its own (each experiment's script is named ``run``), its folder
    on the path for the user's physics beside it."""
    folder = EXPERIMENTS / benchmark(case).folder
    sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location(f"{case}_run", folder / "run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def benchmark_diagnosis(case: str, train: list[Record], validation: list[Record]):
    """The benchmark diagnosed as its experiment does (its discovery aside)."""
    return experiment(case).diagnosed(train[0], validation[0])


def oscillator_diagnosis(train: list[Record], validation: list[Record]):
    return diagnose(Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain")), default_effects(),
                    train, validation)


def perturbed(record: Record, seed: int) -> Record:
    """``record`` with its input and output multiplied by 1 + 1e-12 s, s a random sign per sample."""
    generator = torch.Generator().manual_seed(seed)

    def sign(shape):
        return torch.randint(0, 2, shape, generator=generator).to(torch.float64) * 2 - 1

    return Record(record.t, record.u * (1 + 1e-12 * sign(record.u.shape)), record.y * (1 + 1e-12 * sign(record.y.shape)),
                  record.name, hold=record.hold)


@contextlib.contextmanager
def engine_only():
    """As on a machine without a C compiler: the torch engine for RK4 and TR-BDF2, the scan for linear recurrences."""
    saved = compiled.compiler, compiled._FORMS, compiled._WARNED, scan.sequential_recurrence
    compiled.compiler, compiled._FORMS, compiled._WARNED = (lambda: None), compiled.OrderedDict(), set()
    scan.sequential_recurrence = lambda A, b, z0: None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CompiledPathWarning)
            yield
    finally:
        compiled.compiler, compiled._FORMS, compiled._WARNED, scan.sequential_recurrence = saved


def answer(case: str, train: list[Record], validation: list[Record]) -> dict:
    """The decisions and figures of one diagnosis."""
    started = time.perf_counter()
    diagnosis = (benchmark_diagnosis(case, train, validation) if case in BENCHMARKS
                 else oscillator_diagnosis(train, validation))
    probes = diagnosis.probes
    first = probes.rows[0].place if probes is not None and probes.rows else None
    figures = {f"{h.model}: {name}": getattr(h, name) for h in diagnosis.hybrids
               for name in ("physics_train", "physics_validation", "hybrid_train", "hybrid_validation")}
    return {"added": list(diagnosis.ladder.found), "probes_first": first, "figures": figures,
            "seconds": time.perf_counter() - started}


def compared(reference: dict, other: dict) -> dict:
    """The decisions' agreement, and the largest relative difference of the figures, of all of them and of the
    physics' alone (each rung's physics without the Chebyshev residual)."""
    same = reference["added"] == other["added"] and reference["probes_first"] == other["probes_first"]
    shared = set(reference["figures"]) & set(other["figures"])
    differences = {k: abs(other["figures"][k] - reference["figures"][k]) / max(abs(reference["figures"][k]), 1e-300)
                   for k in shared}
    worst = max(differences, key=differences.get, default=None)
    physics = max((v for k, v in differences.items() if ": physics_" in k), default=0.0)
    return {"decisions_agree": same and len(shared) == len(reference["figures"]),
            "largest_relative": 0.0 if worst is None else differences[worst], "where": worst,
            "largest_relative_physics": physics, "added": other["added"], "seconds": other["seconds"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1200)
    parser.add_argument("--cases", nargs="+", default=[*CASES, *BENCHMARKS], choices=[*CASES, *BENCHMARKS])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    rows = []
    print("| case | run | effects added | decisions agree | largest relative figure difference | where | "
          "the physics' figures | s |")
    print("|---|---|---|---|---|---|---|---|")
    for case in args.cases:
        if not available(case):
            print(f"| {case} | — | left out: no {DATA / benchmark(case).folder} | — | — | — | — | — |")
            continue
        train, validation = records(case, args.samples)
        reference = answer(case, train, validation)
        print(f"| {case} | reference | {', '.join(reference['added']) or 'none'} | — | — | — | — | "
              f"{reference['seconds']:.1f} |", flush=True)
        rows.append({"case": case, "run": "reference", "decisions_agree": None, "largest_relative": None,
                     "where": None, "added": reference["added"], "seconds": reference["seconds"]})
        runs = {"1 thread": (one_thread, train, validation), "engine": (engine_only, train, validation),
                "perturbed 1e-12": (contextlib.nullcontext, [perturbed(r, 2) for r in train],
                                    [perturbed(r, 3) for r in validation])}
        if case in BENCHMARKS:
            del runs["engine"]
        for run, (context, train_run, validation_run) in runs.items():
            with context():
                result = compared(reference, answer(case, train_run, validation_run))
            mark = "yes" if result["decisions_agree"] else "**no**"
            goal = "" if result["largest_relative"] <= GOAL else " (over 1e-6)"
            print(f"| {case} | {run} | {', '.join(result['added']) or 'none'} | {mark} | "
                  f"{result['largest_relative']:.1e}{goal} | {result['where']} | "
                  f"{result['largest_relative_physics']:.1e} | {result['seconds']:.1f} |", flush=True)
            rows.append({"case": case, "run": run, **result})
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"samples": args.samples, "goal": GOAL, "rows": rows}, indent=2))


if __name__ == "__main__":
    main()
