r"""Step doubling: how much a fixed-step method's output depends on its step, and the substeps that make it not matter.

RK4 (or TR-BDF2) advances each sample interval in $m$ substeps. Simulated again at $2m$, the output moves by the gap

$$ g_m = \frac{\|\hat y_m - \hat y_{2m}\|}{\|\hat y_{2m}\|} $$

(norms over every row and sample). Where the solution is smooth a method of order $p$ has $g_m$ equal
to $1 - 2^{-p}$ of the error of $\hat y_m$ and $2^p - 1$ times the error of $\hat y_{2m}$ (RK4: $\tfrac{15}{16}$
and fifteen times; TR-BDF2: $\tfrac34$ and three times); where the physics
has a sharp corner (a smoothed sign) the order is lower and $g_m$ is still an upper bound of the error of
$\hat y_{2m}$ (measured: 6.6 times it on the demo oscillator with Coulomb friction). Two users of the
same estimate:

* :func:`~torchpaml.simulate` with ``substeps="auto"`` (``RK4()``, ``TRBDF2()``, the default ``Auto()``)
  doubles until $g_m \le$ ``rtol`` and returns $\hat y_{2m}$
  (:func:`simulate_to_tolerance`);
* :func:`~torchpaml.fit_physics` checks its fitted output against its misfit
  (:mod:`~torchpaml._fit.resolution`).

Both grow $m$ by the power of two that the method's order predicts brings $g$ to half the target
(:func:`next_substeps`), and both stop at :data:`MAX_SUBSTEPS` with
:class:`~torchpaml.ResolutionError`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from torchpaml._errors import ConfigurationError, ResolutionError, SimulationError

__all__ = ["MAX_SUBSTEPS", "next_substeps", "output_gap", "simulate_to_tolerance"]

#: The most RK4 substeps per sample interval that the step control takes.
MAX_SUBSTEPS = 64


def output_gap(coarse: torch.Tensor, fine: torch.Tensor) -> float:
    r"""$g = \|c - f\| / \|f\|$ over every element (module docstring); 0 where ``fine`` is zero."""
    norm = float(fine.norm())
    return 0.0 if norm == 0.0 else float((coarse - fine).norm()) / norm


def next_substeps(m: int, gap: float, target: float, order: int = 4) -> int:
    """The substeps after ``m`` whose gap a method of ``order`` is predicted to bring to ``target / 2``: ``m`` times
    a power of two, at least 2."""
    return m * 2 ** max(1, math.ceil(math.log2((gap / (target / 2)) ** (1 / order))))


def simulate_to_tolerance(run: Callable[[int], torch.Tensor], start: int, rtol: float, step: float,
                          order: int = 4, method: str = "RK4") -> tuple[torch.Tensor, int]:
    r"""``run(2m)`` for the first $m$ (from ``start``, by :func:`next_substeps`) whose gap $g_m$ is at most ``rtol``,
    and that $2m$.

    ``run(m)`` returns the output at ``m`` substeps. The checks run without gradients; where grad mode is on, the
    accepted output is recorded with them: a fine run that the method's order predicts to pass (every one after the
    first gap) is recorded as it runs, and a first fine run that passes is simulated once more. A first simulation that blows up
    (:class:`~torchpaml.SimulationError`: a rate too fast for the step) is tried again at twice the substeps.
    ``order`` is the method's order (:func:`next_substeps`); ``step`` (the sample interval, s) and ``method`` (its
    name) go into the :class:`~torchpaml.ResolutionError` raised when $2m$ would pass :data:`MAX_SUBSTEPS`.
    """
    if not rtol > 0:
        raise ConfigurationError(f"rtol must be positive, got {rtol}")
    m = min(start, MAX_SUBSTEPS // 2)
    recorded, predicted = torch.is_grad_enabled(), False
    with torch.no_grad():
        coarse = None
        while coarse is None:
            try:
                coarse = run(m)
            except SimulationError:  # too coarse a step for a fast rate: an explicit method left its region of stability
                if 2 * m > MAX_SUBSTEPS // 2:
                    raise
                m *= 2
        while True:
            with torch.set_grad_enabled(recorded and predicted):
                fine = run(2 * m)
            gap = output_gap(coarse, fine.detach())
            if gap <= rtol:
                break
            following = next_substeps(m, gap, rtol, order)
            if 2 * following > MAX_SUBSTEPS:
                raise ResolutionError(
                    f"{method} cannot meet rtol={rtol:g}: halving the step from {m} substeps per sample moved the output "
                    f"by {gap:.3g} of its size, and meeting rtol needs more than {MAX_SUBSTEPS} substeps. A rate of "
                    f"the model is much faster than the sampling (h = {step:g} s), or its physics has a sharp "
                    f"corner. Loosen rtol, fix the step with {method}(substeps=N), integrate stiff physics with "
                    "TRBDF2(), or use Dopri5()")
            coarse, m = (fine.detach(), 2 * m) if following == 2 * m else (run(following), following)
            predicted = True  # the next fine run is the one the order predicts to pass: recorded at once
    return (run(2 * m) if recorded and not predicted else fine), 2 * m
