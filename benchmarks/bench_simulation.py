"""Nonlinear and stiff simulation (parallel in time) against the exact linear path, and one nonlinear fit, in one run.

    python benchmarks/bench_simulation.py [--samples 65536] [--rows 1 64] [--repeats 3] [--dopri5-samples 8000]
                                          [--error-samples 1500]

Two nonlinear models, each against the exact first-order-hold path of the linear Oscillator on the
same input (the baseline), forward alone and forward plus the gradient of a sum of squares:

* mild: Oscillator + CubicStiffness (k3 = 2), h * omega0 = 0.1;
* hard: the same with k3 such that the cubic force is twice the linear one at the RMS of the linear
  response, h * omega0 = 0.2.

Each is timed at one fixed RK4 substep per sample (the engine, ``RK4(substeps=1)``) and as
``simulate(model, t, u)`` does by default (``Auto()``: step doubling to rtol 1e-3). Prints seconds,
nanoseconds per sample and row, and the ratios to exact. Then:

* stiff: Oscillator + InputLag (tau = h / 50: a lag 50 times faster than the sampling), forward, by
  the default (which takes TR-BDF2 there), ``TRBDF2(substeps=1)`` and ``RK4()`` (to rtol 1e-3: the
  substeps that stability needs), each with its ratio to exact and its error against Dopri5;
* the error of the hard model's two rows against Dopri5 at rtol 1e-11 on ``--error-samples`` samples;
* one fit (``fit_physics``) of the mild model, four parameters, on a noisy record of ``--samples`` samples;
* for scale, Dopri5 (rtol 1e-7) forward on ``--dopri5-samples`` samples. One thread.
"""

import argparse
import time

import torch

from torchpaml import (RK4, TRBDF2, CubicStiffness, Dopri5, Exact, Record, InputLag, Oscillator, fit_physics,
                       multisine, simulate)


def best(work, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return min(times)


def drive(samples: int, rows: int, step: float = 0.05) -> tuple[torch.Tensor, torch.Tensor]:
    t = torch.arange(samples, dtype=torch.float64) * step
    u = torch.cat([multisine(t, 1.0, [0.05, 0.1, 0.2, 0.3, 0.5], seed=seed) for seed in range(rows)])
    return t, u


def forward(physics, t, u, **options):
    with torch.no_grad():
        simulate(physics, t, u, **options)


def forward_gradient(physics, t, u, **options):
    physics.zero_grad()
    simulate(physics, t, u, **options).square().sum().backward()


def hard_model(linear, t, u):
    """``linear`` + a cubic stiffness whose force is twice the linear one at the RMS of ``linear``'s response."""
    with torch.no_grad():
        rms = float(simulate(linear, t, u[:1]).square().mean().sqrt())
    omega0 = linear.physical_parameters()["omega0"]
    return Oscillator(**linear.physical_parameters()) + CubicStiffness(2 * omega0**2 / rms**2)


def relative_error(y, reference) -> float:
    return float((y - reference).norm() / reference.norm())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=65536)
    parser.add_argument("--rows", type=int, nargs="+", default=[1, 64])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dopri5-samples", type=int, default=8000)
    parser.add_argument("--error-samples", type=int, default=1500)
    args = parser.parse_args()
    torch.set_num_threads(1)
    linear = Oscillator(zeta=0.2, omega0=2.0, gain=4.0)
    duffing = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(2.0)
    n = args.samples
    print(f"N = {n} samples, one thread; ratios to the exact linear path on the same input")
    print(f"{'model':>22} {'rows':>5} {'pass':>17} {'exact s':>9} {'rk4(1) s':>9} {'ratio':>6} "
          f"{'default s':>10} {'ratio':>6} {'default ns/sample':>18}")
    for label, step in (("mild, h*omega0 = 0.1", 0.05), ("hard, h*omega0 = 0.2", 0.1)):
        for rows in args.rows:
            t, u = drive(n, rows, step)
            model = duffing if step == 0.05 else hard_model(linear, t, u)
            for name, work in (("forward", forward), ("forward+gradient", forward_gradient)):
                exact = best(lambda: work(linear, t, u, solver=Exact()), args.repeats)
                fixed = best(lambda: work(model, t, u, solver=RK4(substeps=1)), args.repeats)
                default = best(lambda: work(model, t, u), args.repeats)
                print(f"{label:>22} {rows:>5} {name:>17} {exact:>9.4f} {fixed:>9.3f} {fixed / exact:>6.1f} "
                      f"{default:>10.3f} {default / exact:>6.1f} {1e9 * default / (n * rows):>18.0f}")
    t, u = drive(n, 1)
    stiff = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + InputLag(tau=0.05 / 50)
    exact = best(lambda: forward(linear, t, u, solver=Exact()), args.repeats)
    short = slice(0, args.error_samples)
    with torch.no_grad():
        reference = simulate(stiff, t[short], u[:, short], solver=Dopri5(rtol=1e-11, atol=1e-12))
    print(f"\nstiff (a lag 50 times faster than the sampling), {n} samples, forward; error on the first "
          f"{args.error_samples} samples against Dopri5 at rtol 1e-11")
    for name, solver in (("default", None), ("TRBDF2(substeps=1)", TRBDF2(substeps=1)), ("RK4()", RK4())):
        seconds = best(lambda: forward(stiff, t, u, solver=solver), args.repeats)
        with torch.no_grad():
            error = relative_error(simulate(stiff, t[short], u[:, short], solver=solver), reference)
        print(f"{name:>22} {seconds:>9.3f} s  ratio to exact {seconds / exact:>6.1f}  error {error:.2e}")
    t, u = drive(args.error_samples, 1, 0.1)
    hard = hard_model(linear, t, u)
    with torch.no_grad():
        reference = simulate(hard, t, u, solver=Dopri5(rtol=1e-11, atol=1e-12))
        errors = {name: relative_error(simulate(hard, t, u, solver=solver), reference)
                  for name, solver in (("rk4(1)", RK4(substeps=1)), ("default", None))}
    print(f"\nhard model, {args.error_samples} samples, relative RMS error against dopri5 at rtol 1e-11: "
          + ", ".join(f"{name} {error:.2e}" for name, error in errors.items()))
    t, u = drive(n, 1)
    with torch.no_grad():
        y = simulate(duffing, t, u)
    y = y + 0.02 * y.std() * torch.randn(y.shape, generator=torch.Generator().manual_seed(0))
    record = Record(t, u[0], y[0], "duffing")
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
    dopri5 = best(lambda: forward(duffing, t, u, solver=Dopri5()), 1)
    rk4 = best(lambda: forward(duffing, t, u), args.repeats)
    print(f"dopri5 forward on {m} samples: {dopri5:.2f} s ({1e6 * dopri5 / m:.0f} us/sample); the default {rk4:.3f} s: "
          f"{dopri5 / rk4:.0f} x faster")


if __name__ == "__main__":
    main()
