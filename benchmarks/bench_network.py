"""The discovery's neural rate: its tanh network folded into sigmoids against the plain ``nn.Sequential``, same run.

    python benchmarks/bench_network.py [--samples 50000] [--max-iter 6]

Data: the oscillator with a hidden cubic damping (the discovery cases' first), 20 Hz, 2 % noise, one pseudorandom
record of ``--samples`` samples; the linear oscillator fitted on it. Timed: :func:`~torchpaml._fit.neural_force.
fit_neural_force` with ``max_iter`` L-BFGS iterations, once with the networks as they are
(:class:`~torchpaml._residual.mlp.TanhNetwork`) and once with the same layers run by ``nn.Sequential`` (``torch.tanh``),
the baseline; the same seed, so the same network and the same search. Reported: seconds, the ratio, µs per sample and
evaluation, and the two fits' mismatches (they agree to rounding). One thread.
"""

import argparse
import time
from unittest import mock

import torch
from bench_discovery import CubicDamping
from bench_diagnosis import physics
from torch import nn
from torchpaml import Oscillator, Simulated, fit_physics
from torchpaml._fit.neural_force import fit_neural_force
from torchpaml._residual.mlp import TanhNetwork


def timed_fit(fitted, records, max_iter: int):
    """(seconds, the fit) of one neural rate on ``fitted``."""
    start = time.perf_counter()
    fit = fit_neural_force(fitted, records, max_iter=max_iter)
    return time.perf_counter() - start, fit


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=50_000)
    parser.add_argument("--max-iter", type=int, default=6)
    args = parser.parse_args()
    torch.set_num_threads(1)
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CubicDamping(0.5)
    records = Simulated(truth, "pseudorandom", 1.0, [0], args.samples * 0.05, 0.05, noise=0.02).experiments()
    fitted = physics()
    fit_physics(fitted, records)
    calls = {"folded": 0, "plain": 0}
    folded_forward = TanhNetwork.forward

    def counted(kind, forward):
        def run(self, h):
            calls[kind] += 1
            return forward(self, h)
        return run

    rows = {}
    for kind, forward in (("plain", nn.Sequential.forward), ("folded", folded_forward)):
        with mock.patch.object(TanhNetwork, "forward", counted(kind, forward)):
            timed_fit(fitted, records, 1)  # warm-up: torch's first calls
            calls[kind] = 0
            rows[kind] = timed_fit(fitted, records, args.max_iter)
    n = len(records[0].t)
    print(f"neural rate on {n} samples, max_iter {args.max_iter}, one thread")
    print("| network | seconds | ratio | network calls | µs per sample and call | mismatch |")
    print("|---|---|---|---|---|---|")
    base = rows["plain"][0]
    for kind, label in (("plain", "nn.Sequential (torch.tanh), the baseline"), ("folded", "TanhNetwork (the default)")):
        seconds, fit = rows[kind]
        print(f"| {label} | {seconds:.2f} | {seconds / base:.2f} | {calls[kind]} | "
              f"{1e6 * seconds / n / max(calls[kind], 1):.3f} | {fit.mismatch:.10f} |")


if __name__ == "__main__":
    main()
