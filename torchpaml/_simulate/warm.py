"""The RK4 engine's warm start: the last converged trajectory of one record, kept between solves."""

from __future__ import annotations

from dataclasses import dataclass

import torch

__all__ = ["WarmStart"]


@dataclass
class WarmStart:
    """The converged states of the last RK4 solve of one record, which start the next solve's Newton.

    A caller keeps one per record between solves under nearby parameters (a fit's iterations, a training
    run's steps, the probes of one effect): Newton then needs a sweep or two instead of the several of a cold
    start, and the solution does not depend on it. Start with ``WarmStart()``; every solve that is given it
    stores its trajectory here.

    Attributes:
        states: (batch, time, n_state), or ``None`` before the first solve.
    """

    states: torch.Tensor | None = None
