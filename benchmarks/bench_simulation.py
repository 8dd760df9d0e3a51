"""Nonlinear RK4 (parallel in time) against the exact linear path, and one nonlinear fit, in one run.

    python benchmarks/bench_simulation.py [--samples 65536] [--rows 1 64] [--repeats 3] [--dopri5-samples 8000]

For each row count: the exact first-order-hold path of the linear Oscillator (the baseline), and
RK4 of Oscillator + CubicStiffness (k3 = 2, hardening) on the same input, forward alone and forward
plus the gradient of a sum of squares. Prints seconds, nanoseconds per sample and row, and the ratio
RK4 / exact. Then one fit (``fit_physics``) of Oscillator + CubicStiffness, four parameters, on a
noisy record of ``--samples`` samples, and, for scale, dopri5 (rtol 1e-7) forward on
``--dopri5-samples`` samples. One thread.
"""

import argparse
import time

import torch

from torchpaml import CubicStiffness, Experiment, fit_physics, multisine, Oscillator, simulate


def best(work, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return min(times)


def drive(samples: int, rows: int) -> tuple[torch.Tensor, torch.Tensor]:
    t = torch.arange(samples, dtype=torch.float64) * 0.05
    u = torch.cat([multisine(t, 1.0, [0.05, 0.1, 0.2, 0.3, 0.5], seed=seed) for seed in range(rows)])
    return t, u


def forward(physics, t, u, method):
    with torch.no_grad():
        simulate(physics, t, u, method=method)


def forward_gradient(physics, t, u, method):
    physics.zero_grad()
    simulate(physics, t, u, method=method).square().sum().backward()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=65536)
    parser.add_argument("--rows", type=int, nargs="+", default=[1, 64])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dopri5-samples", type=int, default=8000)
    args = parser.parse_args()
    torch.set_num_threads(1)
    linear = Oscillator(zeta=0.2, omega0=2.0, gain=4.0)
    duffing = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(2.0)
    n = args.samples
    print(f"N = {n} samples, h*omega0 = 0.1, one thread")
    print(f"{'rows':>5} {'pass':>17} {'exact s':>9} {'rk4 s':>8} {'rk4 ns/sample':>14} {'rk4/exact':>10}")
    for rows in args.rows:
        t, u = drive(n, rows)
        for name, work in (("forward", forward), ("forward+gradient", forward_gradient)):
            exact = best(lambda: work(linear, t, u, "exact"), args.repeats)
            rk4 = best(lambda: work(duffing, t, u, "rk4"), args.repeats)
            print(f"{rows:>5} {name:>17} {exact:>9.4f} {rk4:>8.3f} {1e9 * rk4 / (n * rows):>14.0f} {rk4 / exact:>10.1f}")
    t, u = drive(n, 1)
    with torch.no_grad():
        y = simulate(duffing, t, u, method="rk4")
    y = y + 0.02 * y.std() * torch.randn(y.shape, generator=torch.Generator().manual_seed(0))
    record = Experiment(t, u[0], y[0], "duffing")
    model = Oscillator(zeta=0.4, omega0=1.8, gain=3.0, learn=("zeta", "omega0", "gain")) + CubicStiffness(1.0)
    start = time.perf_counter()
    fit = fit_physics(model, record)
    seconds = time.perf_counter() - start
    exact_fit = best(lambda: fit_physics(Oscillator(zeta=0.4, omega0=1.8, gain=3.0, learn=("zeta", "omega0", "gain")),
                                         record), 1)
    print(f"\none fit of Oscillator + CubicStiffness on {n} samples: {seconds:.2f} s, {fit.evaluations} simulations, "
          + ", ".join(f"{k} = {v:.4f}" for k, v in fit.parameters.items())
          + f" (truth 0.2, 2, 4, 2); the linear Oscillator's fit on the same record: {exact_fit:.2f} s")
    m = args.dopri5_samples
    t, u = drive(m, 1)
    dopri5 = best(lambda: forward(duffing, t, u, "dopri5"), 1)
    rk4 = best(lambda: forward(duffing, t, u, "rk4"), args.repeats)
    print(f"dopri5 forward on {m} samples: {dopri5:.2f} s ({1e6 * dopri5 / m:.0f} us/sample); rk4 {rk4:.3f} s: "
          f"{dopri5 / rk4:.0f} x faster")


if __name__ == "__main__":
    main()
