"""One fit evaluation (the output and its Jacobian) against one compiled forward simulation of the same record.

    python benchmarks/bench_fit_evaluation.py [--samples 65536] [--repeats 5]

The hard oscillator (an oscillator with a strong cubic spring, ``zeta``, ``omega0``, ``gain`` and ``k3`` learnable:
p = 4, and the two initial-state columns), RK4 at one substep, a pseudorandom input. Timed, best of ``--repeats``, in
the same run: the compiled forward simulation (the states; the baseline), the compiled evaluation (outputs and the
exact Jacobian in one pass), and the torch engine's evaluation (one Newton solve and a central difference of two
sweeps per column). Reported: µs per sample, and the evaluation's ratio to the forward simulation against the goal
2(p + 1). One thread.
"""

from __future__ import annotations

import argparse

import torch
from bench_simulation import best  # the best of repeats, as the simulation benchmark times

from torchpaml import RK4, CubicStiffness, Oscillator
from torchpaml._signals import pseudorandom
from torchpaml._simulate.compiled import sequential_states
from torchpaml._simulate.compiled_jacobian import compiled_jacobian
from torchpaml._simulate.sensitivity import raw_parameters, shooting_jacobian


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=65536)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    torch.set_num_threads(1)
    physics = Oscillator(zeta=0.1, omega0=1.0, gain=1.0, learn=("zeta", "omega0", "gain")) + CubicStiffness(200.0)
    t = torch.arange(args.samples, dtype=torch.float64) * 0.05
    u = 0.1 * pseudorandom(t, 1.0, seed=0).reshape(1, -1, 1)
    x0 = torch.tensor([[0.05, 0.0]], dtype=torch.float64)
    raw = raw_parameters(physics, physics.learnable_names())
    solver = RK4(substeps=1)
    p = len(raw)
    forward = lambda: sequential_states(physics, t, u, x0, solver, "foh")  # noqa: E731
    evaluation = lambda: compiled_jacobian(physics, raw, t, u, x0, solver, "foh", True)  # noqa: E731
    engine = lambda: shooting_jacobian(physics, raw, t, u, x0, solver, None, True, "foh")  # noqa: E731
    assert forward() is not None and evaluation() is not None  # compiled here, before the timing
    with torch.no_grad():
        seconds = {name: best(work, args.repeats if name != "engine" else 1)
                   for name, work in (("forward", forward), ("evaluation", evaluation), ("engine", engine))}
    micro = {name: 1e6 * s / args.samples for name, s in seconds.items()}
    print(f"{args.samples} samples, p = {p} parameters and 2 initial-state columns, RK4 at one substep, one thread")
    print("| run | µs per sample | against the compiled forward simulation |")
    print("|---|---|---|")
    print(f"| compiled forward simulation (states) | {micro['forward']:.3f} | 1 |")
    print(f"| compiled evaluation (outputs and Jacobian) | {micro['evaluation']:.3f} | "
          f"{seconds['evaluation'] / seconds['forward']:.1f}× (goal ≤ 2(p + 1) = {2 * (p + 1)}) |")
    print(f"| engine evaluation (Newton, central differences) | {micro['engine']:.2f} | "
          f"{seconds['engine'] / seconds['forward']:.0f}× |")


if __name__ == "__main__":
    main()
