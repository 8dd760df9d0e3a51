"""The default step control on a hard oscillator: seconds and ratio to the exact linear path, and the error against
the tolerance asked for, in one run.

    python benchmarks/bench_step_control.py [--samples 65536] [--error-samples 4000] [--repeats 2]

The model: ``Oscillator(zeta=0.1, omega0=1, gain=1) + CubicStiffness(200)`` (the cubic force twice the linear one at
x = 0.1), sampled at h = 0.2 s (h * omega0 = 0.2), driven by 0.1 * randn (seed 0). The baseline: the exact
first-order-hold path of the linear Oscillator on the same input, forward and forward plus the gradient of a sum of
squares. The default ``simulate`` (``Auto(rtol=1e-3)``) and ``RK4(substeps=1)`` are timed, also per sample against
the limit of a 2-state model (1 us per sample); their error is the relative RMS error against Dopri5 at rtol 1e-11 on
the first ``--error-samples`` samples. Prints the step doubling's levels and gaps. One thread. The best of
``--repeats`` runs: the model's compiled RK4 (torchpaml._simulate.compiled) is built in the first run and reused.
"""

import argparse
import time

import torch

from torchpaml import RK4, CubicStiffness, Dopri5, Exact, Oscillator, simulate
from torchpaml._simulate import step_control

from bench_simulation import best, forward, forward_gradient  # the same timing as the simulation benchmark's

RTOL = 1e-3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=65536)
    parser.add_argument("--error-samples", type=int, default=4000)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(1)
    t = torch.arange(args.samples, dtype=torch.float64) * 0.2
    u = 0.1 * torch.randn(1, args.samples, 1, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    linear = Oscillator(zeta=0.1, omega0=1.0, gain=1.0)
    hard = Oscillator(zeta=0.1, omega0=1.0, gain=1.0, learn=("zeta", "omega0")) + CubicStiffness(200.0)
    print(f"hard oscillator, {args.samples} samples, one thread; rtol {RTOL:g}")
    gaps = []
    original = step_control.output_gap
    step_control.output_gap = lambda coarse, fine: gaps.append(original(coarse, fine)) or gaps[-1]
    start = time.perf_counter()
    forward(hard, t, u)
    first = time.perf_counter() - start
    step_control.output_gap = original
    print(f"first forward call, the model traced and its RK4 compiled (or loaded from the cache): {first:.3f} s")
    print("step doubling's gaps: " + ", ".join(f"{g:.2e}" for g in gaps))
    for name, work in (("forward", forward), ("forward+gradient", forward_gradient)):
        exact = best(lambda: work(linear, t, u, solver=Exact()), args.repeats)
        default = best(lambda: work(hard, t, u), args.repeats)
        fixed = best(lambda: work(hard, t, u, solver=RK4(substeps=1)), args.repeats)
        print(f"{name:>17}: exact {exact:.4f} s; default {default:.3f} s ({default / exact:.0f}x, "
              f"{default / args.samples * 1e6:.2f} us per sample: {default / args.samples * 1e6:.2g}x the 1 us limit); "
              f"RK4(substeps=1) {fixed:.3f} s ({fixed / exact:.0f}x, {fixed / args.samples * 1e6:.2f} us per sample)")
    short = slice(0, args.error_samples)
    with torch.no_grad():
        reference = simulate(hard, t[short], u[:, short], solver=Dopri5(rtol=1e-11, atol=1e-12))
    for name, solver in (("default", None), ("RK4(substeps=1)", RK4(substeps=1))):
        with torch.no_grad():
            y = simulate(hard, t[short], u[:, short], solver=solver)
        error = float((y - reference).norm() / reference.norm())
        print(f"error of {name} on {args.error_samples} samples: {error:.2e} (rtol {RTOL:g}: {error / RTOL:.2g} of it)")


if __name__ == "__main__":
    main()
