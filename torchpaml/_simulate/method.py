"""What the shooting engine needs of a one-step method: the :class:`Method` protocol, which
:class:`~torchpaml._simulate.solvers.FixedStep` (RK4, TR-BDF2, a user's own) implements."""

from __future__ import annotations

from typing import Literal, Protocol

import torch

from torchpaml._simulate.dynamics import Dynamics

__all__ = ["Method"]


class Method(Protocol):
    """A one-step method on the sample grid (:class:`~torchpaml._simulate.solvers.FixedStep`'s attributes)."""

    substeps: int | Literal["auto"]
    rtol: float
    segment: int
    order: int
    middle: float
    coefficients: tuple[float, ...]
    stability: float | None
    compiles: str | None

    def at(self, substeps: int) -> Method:
        """The method with ``substeps`` fixed."""

    def sweep(self, physics: Dynamics, x: torch.Tensor, stages) -> torch.Tensor:
        """One step per stage for the rows of ``x`` (rows, n): the states at the step boundaries, (n, L + 1, rows)."""
