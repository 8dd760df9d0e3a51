"""The step of every central difference of a simulation (:mod:`~torchpaml._simulate.sensitivity`'s of the engine's
sweeps, :mod:`~torchpaml._simulate.compiled_jacobian`'s of compiled simulations of a kinked physics), so that the two
paths' Jacobians differ by rounding only."""

from __future__ import annotations

__all__ = ["DIFFERENCE_STEP", "difference_step"]

#: Central-difference step, relative to max(1, |value|): truncation error ~1e-12, rounding ~1e-10.
DIFFERENCE_STEP = 1e-6


def difference_step(largest: float) -> float:
    """The step $s = $ :data:`DIFFERENCE_STEP` $\\cdot\\max(1, |v|)$ for a value whose largest magnitude is
    ``largest``."""
    return DIFFERENCE_STEP * max(1.0, abs(largest))
