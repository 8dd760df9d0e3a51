"""Tracking a 2-state model at 1 kHz: seconds per sample of the filter and its detector, fed as one block and one
sample at a time, against the model's own simulation of the same record (the baseline, in the same run); then the
detector's false alarms and detection delay, measured on streams that start in motion.

    python benchmarks/bench_tracking.py [--seconds 100] [--repeats 3] [--streams 100] [--changed 20]
                                        [--out results/bench_tracking.json]

The model: ``Oscillator(zeta=0.1, omega0=5, gain=25) + CoulombFriction(1)``, h = 1 ms, driven by a pseudorandom
input, its output with 1 % noise. Prints microseconds per sample (the filter from a known start; the start's
estimate, paid once per stream, apart), the margin over real time (1000 us per sample at 1 kHz divided by the cost),
and the ratio to ``simulate`` with the model's solver (``RK4(substeps=1)``) and to one microsecond per sample. One
thread.

The detector: ``--streams`` unchanged streams of 12 s, each starting after 3 s of driving (in motion), tracked with
the defaults (start estimated, alpha 1e-9): the false alarms counted, per hour of stream, beside the expected rate at
alpha and the 95 % upper bound where none was seen (3 / hours, the rule of three); ``--changed`` streams whose
friction doubles 6 s in: the delay from the change to the alarm, and how often the alarm names
``coulomb_friction.Fc``.
"""

import argparse
import copy
import json
import time
from pathlib import Path

import numpy as np
import torch

from torchpaml import (RK4, CoulombFriction, FittedModel, Oscillator, Record, Tracker, pseudorandom, simulate,
                       time_grid, track)

from bench_simulation import best  # the same timing as the simulation benchmark's

H = 0.001


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=100.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--streams", type=int, default=100)
    parser.add_argument("--changed", type=int, default=20)
    parser.add_argument("--out", help="JSON file for the figures")
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
    rest = (0.0, 0.0)  # the record starts at rest: the filter's own cost, without the start's estimate
    Tracker(model)  # compile the filter once (cached), outside the timings
    baseline = best(lambda: model.simulate(record), args.repeats)
    block = best(lambda: Tracker(model, x0=rest).feed(record), args.repeats)
    estimate = best(lambda: Tracker(model).feed(record.window(0, 500)), args.repeats)
    T, U, Y = record.t.numpy(), record.u.numpy(), record.y.numpy()

    def one_at_a_time():
        tracker = Tracker(model, x0=rest)
        for k in range(n):
            tracker.update(T[k], U[k], Y[k])

    per_sample = best(one_at_a_time, args.repeats)
    print(f"{n} samples at 1 kHz ({args.seconds:g} s of stream), 2 states, one thread")
    print(f"  simulate (baseline, RK4(substeps=1)): {baseline:.3f} s, {baseline / n * 1e6:.3f} us/sample")
    figures = {"samples": n, "simulate_s": baseline, "start_estimate_s": estimate}
    for name, key, seconds in (("feed(record), one block", "block", block),
                               ("update(t, u, y), per sample", "per_sample", per_sample)):
        us = seconds / n * 1e6
        figures[f"{key}_us_per_sample"] = us
        print(f"  {name}: {seconds:.3f} s, {us:.3f} us/sample = {1000 / us:.0f}x real time; "
              f"{seconds / baseline:.2f}x simulate; {us:.2f}x the 1 us/sample limit")
    print(f"  the start estimated on the first window (500 samples), once per stream: {estimate:.3f} s")
    figures.update(detector(physics, sigma, args.streams, args.changed))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(figures, indent=2))


#: The streams of the detector's figures: seconds of driving before the stream starts, its length, the change's time.
MOVING, LENGTH, CHANGE = 3.0, 12.0, 6.0


def _stream(physics, changed, seed: int, sigma: float) -> Record:
    """``physics`` driven for MOVING + LENGTH s, ``changed`` from MOVING + CHANGE on; the last LENGTH s measured."""
    t = time_grid(MOVING + LENGTH, H)
    u = pseudorandom(t, 1.0, seed=seed)
    k, first = round((MOVING + CHANGE) / H), round(MOVING / H)
    with torch.no_grad():
        before = RK4(substeps=1).states(physics, t[: k + 1], u[:, : k + 1], physics.initial_state(1))
        after = RK4(substeps=1).states(changed, t[k:], u[:, k:], before[:, -1])
        y = torch.cat([physics.output(before, u[:, : k + 1]), changed.output(after[:, 1:], u[:, k + 1:])], dim=1)[0]
    y = y[first:] + sigma * torch.randn(y[first:].shape, generator=torch.Generator().manual_seed(seed),
                                        dtype=torch.float64)
    return Record(t[first:] - t[first], u[0, first:], y)


def detector(physics, sigma: float, streams: int, changed: int) -> dict:
    """False alarms on ``streams`` unchanged streams and the delays on ``changed`` streams (module docstring)."""
    model = FittedModel(physics, RK4(substeps=1), step=H, noise=(sigma,))
    doubled = copy.deepcopy(physics).assign(**{"coulomb_friction.Fc": 2.0})
    started = time.perf_counter()
    alarms = 0
    for seed in range(streams):
        alarms += len(track(model, _stream(physics, physics, 1000 + seed, sigma)).alarms)
        if (seed + 1) % 25 == 0:
            print(f"  unchanged streams: {seed + 1} of {streams} tracked, {alarms} false alarm(s) "
                  f"({time.perf_counter() - started:.0f} s)", flush=True)
    hours = streams * LENGTH / 3600
    expected = Tracker(model).false_alarms_per_hour
    delays, named = [], 0
    for seed in range(changed):
        found = track(model, _stream(physics, doubled, 2000 + seed, sigma)).alarms
        after = [a for a in found if a.t >= CHANGE]
        if after:
            delays.append(after[0].t - CHANGE)
            named += after[0].parameter == "coulomb_friction.Fc"
    rate = alarms / hours
    bound = (3.0 if alarms == 0 else float("nan")) / hours
    print(f"  false alarms: {alarms} in {streams} unchanged streams ({hours:.3f} h of stream, starting in motion): "
          f"{rate:.3g} per hour" + (f" (95 % upper bound {bound:.3g} per hour)" if alarms == 0 else "")
          + f"; expected at alpha = 1e-9: at most {expected:.3g} per hour")
    print(f"  friction doubled: flagged in {len(delays)} of {changed} streams, delay median "
          f"{np.median(delays):.3f} s, max {max(delays):.3f} s; named coulomb_friction.Fc in {named}")
    return {"unchanged_streams": streams, "stream_hours": hours, "false_alarms": alarms,
            "false_alarms_per_hour": rate, "false_alarms_per_hour_upper_95": bound if alarms == 0 else None,
            "expected_false_alarms_per_hour": expected, "changed_streams": changed, "flagged": len(delays),
            "delay_median_s": float(np.median(delays)), "delay_max_s": float(max(delays)), "named": named}


if __name__ == "__main__":
    main()
