"""Tracking a 2-state model at 1 kHz: seconds per sample of the filter and its detector, fed as one block and one
sample at a time, against the model's own simulation of the same record (the baseline, in the same run).

    python benchmarks/bench_tracking.py [--seconds 100] [--repeats 3]

The model: ``Oscillator(zeta=0.1, omega0=5, gain=25) + CoulombFriction(1)``, h = 1 ms, driven by a pseudorandom
input, its output with 1 % noise. Prints microseconds per sample, the margin over real time (1000 us per sample at
1 kHz divided by the cost), and the ratio to ``simulate`` with the model's solver (``RK4(substeps=1)``) and to one
microsecond per sample. One thread.
"""

import argparse

import torch

from torchpaml import RK4, CoulombFriction, FittedModel, Oscillator, Record, Tracker, pseudorandom, simulate, time_grid

from bench_simulation import best  # the same timing as the simulation benchmark's

H = 0.001


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=100.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    torch.set_num_threads(1)
    t = time_grid(args.seconds, H)
    u = pseudorandom(t, 1.0, seed=0)
    physics = Oscillator(zeta=0.1, omega0=5.0, gain=25.0) + CoulombFriction(1.0)
    with torch.no_grad():
        y = simulate(physics, t, u, solver=RK4(substeps=1))
    sigma = float(0.01 * y.std())
    y = y + sigma * torch.randn(y.shape, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    record = Record(t, u[0], y[0])
    model = FittedModel(physics, RK4(substeps=1), step=H, noise=(sigma,))
    n = len(t)
    Tracker(model)  # compile the filter once (cached), outside the timings
    baseline = best(lambda: model.simulate(record), args.repeats)
    block = best(lambda: Tracker(model).feed(record), args.repeats)
    T, U, Y = record.t.numpy(), record.u.numpy(), record.y.numpy()
    single = min(args.repeats, 2)

    def one_at_a_time():
        tracker = Tracker(model)
        for k in range(n):
            tracker.update(T[k], U[k], Y[k])

    per_sample = best(one_at_a_time, single)
    print(f"{n} samples at 1 kHz ({args.seconds:g} s of stream), 2 states, one thread")
    print(f"  simulate (baseline, RK4(substeps=1)): {baseline:.3f} s, {baseline / n * 1e6:.3f} us/sample")
    for name, seconds in (("feed(record), one block", block), ("update(t, u, y), per sample", per_sample)):
        us = seconds / n * 1e6
        print(f"  {name}: {seconds:.3f} s, {us:.3f} us/sample = {1000 / us:.0f}x real time; "
              f"{seconds / baseline:.2f}x simulate; {us:.2f}x the 1 us/sample limit")


if __name__ == "__main__":
    main()
