"""The linear recurrence of linear physics and of the Chebyshev residual: C's sequential loop against the scan.

    python benchmarks/bench_recurrence.py [--lengths 10000 100000 1000000] [--repeats 3]

The recurrence $z_{s+1} = A z_s + b_s$ (``constant_recurrence``) for a 2-state model (an oscillator's exact
discretisation, one row) and for the Chebyshev residual's regressors (its default fifth-order filter at h = 1 ms, six
feature rows), forward and forward plus the gradient of a sum of squares in A, b and z0. The baseline is the scan it
falls back to (no compiler), timed in the same run; the states of the two agree to rounding (printed). One thread,
the best of ``--repeats``.
"""

import argparse
import time

import numpy as np
import torch

from torchpaml._simulate import scan
from torchpaml._simulate.lti import discretize
from torchpaml._simulate.scan import constant_recurrence


def systems() -> dict[str, tuple[torch.Tensor, int]]:
    """name -> (the discrete state matrix, rows)."""
    oscillator = torch.tensor([[0.0, 1.0], [-4.0, -0.8]], dtype=torch.float64)  # omega0 2, zeta 0.2
    poles = [complex(-1.5, 1.0), complex(-1.5, -1.0), complex(-1.5, 6.0), complex(-1.5, -6.0), -1.5]
    denominator = torch.tensor(np.real(np.poly(poles)), dtype=torch.float64)
    companion = torch.cat([torch.eye(5, dtype=torch.float64)[1:], -denominator.flip(0)[:5][None]])
    B2, B5 = torch.zeros(2, 1, dtype=torch.float64), torch.zeros(5, 1, dtype=torch.float64)
    return {"2-state model, 1 row (h = 0.05 s)": (discretize(oscillator, B2, 0.05)[0], 1),
            "residual's filter, 6 rows (h = 1 ms)": (discretize(companion, B5, 1e-3)[0], 6)}


def timed(work, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        work()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    torch.set_num_threads(1)
    stepped = scan.sequential_recurrence
    print("| system | samples | pass | scan (baseline) | C loop | ratio | C per sample and row | states apart |")
    print("|---|---|---|---|---|---|---|---|")
    for name, (A, rows) in systems().items():
        n = A.shape[0]
        for samples in args.lengths:
            generator = torch.Generator().manual_seed(0)
            b = torch.randn(rows, samples - 1, n, generator=generator, dtype=torch.float64)
            z0 = torch.zeros(rows, n, dtype=torch.float64)

            def forward():
                with torch.no_grad():
                    return constant_recurrence(A, b, z0)

            def gradient():
                inputs = [x.clone().requires_grad_() for x in (A, b, z0)]
                constant_recurrence(*inputs).square().sum().backward()

            times = {}
            for path in ("scan", "C"):
                scan.sequential_recurrence = (lambda *_: None) if path == "scan" else stepped
                times[path] = {"forward": timed(forward, args.repeats), "forward + gradient": timed(gradient,
                                                                                                       args.repeats)}
                times[path]["states"] = forward()
            scan.sequential_recurrence = stepped
            apart = float((times["C"]["states"] - times["scan"]["states"]).abs().max()
                          / times["scan"]["states"].abs().max())
            for kind in ("forward", "forward + gradient"):
                slow, fast = times["scan"][kind], times["C"][kind]
                print(f"| {name} | {samples:,} | {kind} | {1e3 * slow:.2f} ms | {1e3 * fast:.2f} ms | "
                      f"{slow / fast:.1f}× | {1e6 * fast / samples / rows:.4f} µs | {apart:.1e} |", flush=True)


if __name__ == "__main__":
    main()
