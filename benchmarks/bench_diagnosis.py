"""How the diagnosis' time grows with the record's length, against one physics fit measured in the same run.

    python benchmarks/bench_diagnosis.py [--lengths 10000 100000]

Data: the demo system (the oscillator with a hidden Coulomb friction), 20 Hz, 2 % noise, a
pseudorandom training record and a multisine validation record of each length. For each length: one
fit of the physics alone (the baseline, linear: exact simulation; the faster of two, as the first call in a
process also warms torch up) and the whole diagnosis with the
library effects (nineteen) (:func:`~torchpaml.diagnose`: the ladder and the Chebyshev residual on top).
Reported: seconds (the first diagnosis in the process, and the same diagnosis again: the first also reads the
candidates' compiled forms), microseconds per sample, the ratio to the fit, and the time per sample against the
shortest record's (1.0 is linear in N), all of the first. Two threads, the machine's.
"""

import argparse
import time

from torchpaml import CoulombFriction, Oscillator, Simulated, default_effects, diagnose, fit_physics


def physics():
    """The diagnosed physics: the linear oscillator, every parameter learnable, started 25-75 % off."""
    return Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain"))


def timed(work) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def rows_by_length(truth, lengths: list[int], job: str, work, again: bool = False) -> None:
    """Print one table row per record length: one physics fit (the baseline) and ``work(train, validation)``
    (which returns what it found, as text), each timed, on records of ``truth`` at 20 Hz with 2 % noise; with
    ``again``, the work's time when it is run a second time in the process too."""
    second = f" {job} again s |" if again else ""
    print(f"| samples | physics fit s | {job} s |{second} µs per sample | {job} / fit | per sample vs first | found |")
    print("|---|---|---|---|---|---|---|" + ("---|" if again else ""))
    first = None
    for n in lengths:
        records = dict(amplitude=1.0, duration=n * 0.05, dt=0.05, noise=0.02)
        train = Simulated(truth, "pseudorandom", seeds=[0], **records).experiments()
        validation = Simulated(truth, "multisine", seeds=[1], **records).experiments()
        fit = min(timed(lambda: fit_physics(physics(), train)) for _ in range(2))  # the first call warms torch up
        start = time.perf_counter()
        found = work(train, validation)
        seconds = time.perf_counter() - start
        repeated = f" {timed(lambda: work(train, validation)):.2f} |" if again else ""
        per = seconds / len(train[0].t)
        first = first or per
        print(f"| {len(train[0].t)} | {fit:.2f} | {seconds:.1f} |{repeated} {1e6 * per:.0f} | {seconds / fit:.0f}x | "
              f"{per / first:.2f} | {found} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="+", default=[10_000, 100_000])
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CoulombFriction(0.5)

    def work(train, validation):
        return ", ".join(diagnose(physics(), default_effects(), train, validation).ladder.added)

    rows_by_length(truth, parser.parse_args().lengths, "diagnosis", work, again=True)


if __name__ == "__main__":
    main()
