"""Exact discretisation vs torchdiffeq dopri5 (rtol 1e-7, float64) for the linear physics, forward + backward.

    python benchmarks/bench_simulation.py [--sizes 8000 800000] [--repeats 3]

Prints wall times and the ratio dopri5 / exact measured in the same run. The 800 000-sample ODE
run takes minutes on 2 cores; pass --ode-limit to skip ODE sizes above it.
"""

import argparse
import time

import torch

from torchpaml import Oscillator, simulate
from torchpaml.signals import pseudorandom, pseudorandom_knots, time_grid


def forward_backward(method: str, n: int) -> float:
    t = time_grid(n * 0.01, 0.01)
    u = pseudorandom(t, 4.0, seed=0)
    physics = Oscillator(zeta=0.6)
    options = {"rtol": 1e-7, "atol": 1e-9, "knots": pseudorandom_knots(t)} if method == "dopri5" else {}
    start = time.perf_counter()
    simulate(physics, t, u, method=method, **options).square().sum().backward()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[8000, 800000])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--ode-limit", type=int, default=10**9, help="skip dopri5 above this many samples")
    args = parser.parse_args()
    torch.set_num_threads(2)
    print(f"{'N':>9} {'exact s':>10} {'dopri5 s':>10} {'dopri5/exact':>13}")
    for n in args.sizes:
        exact = min(forward_backward("exact", n) for _ in range(args.repeats))
        if n > args.ode_limit:
            print(f"{n:>9} {exact:>10.4f} {'skipped':>10} {'-':>13}")
            continue
        ode = min(forward_backward("dopri5", n) for _ in range(1 if n > 100000 else args.repeats))
        print(f"{n:>9} {exact:>10.4f} {ode:>10.3f} {ode / exact:>13.0f}")


if __name__ == "__main__":
    main()
