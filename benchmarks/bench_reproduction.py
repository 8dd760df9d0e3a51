"""Wall time of the full paper reproduction (both amplitudes, 10 seeds), against one physics fit.

    python benchmarks/bench_reproduction.py

The baseline measured in the same run is one stage-1 fit (bounded scalar PEM on the sine).
"""

import time

import torch

from torchpaml import Record, fit_physics, Oscillator, sine, time_grid
from torchpaml._paper import PaperSetup, _measure, reproduce


def main() -> None:
    torch.set_num_threads(2)
    setup = PaperSetup()
    t = time_grid(setup.duration, setup.dt)
    u = sine(t, 4.0, setup.omega)
    y = _measure(setup, t, u)
    start = time.perf_counter()
    fit_physics(Oscillator(zeta=1.0), Record.records(t, u, y), bounds={"zeta": setup.zeta_bounds})
    one_fit = time.perf_counter() - start
    start = time.perf_counter()
    reproduce([4.0, 10.0], seeds=10)
    full = time.perf_counter() - start
    print(f"one physics fit: {one_fit:.3f} s")
    print(f"full reproduction (alpha 4 and 10, 10 seeds): {full:.1f} s = {full / one_fit:.0f} x one physics fit")


if __name__ == "__main__":
    main()
