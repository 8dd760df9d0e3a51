"""Time-grid helpers shared by the records and the simulators: the input holds and the uniform step.

At the bottom of the import graph: :mod:`torchpaml._data` and :mod:`torchpaml._simulate` both build on it.
"""

from __future__ import annotations

import torch

from torchpaml._errors import ConfigurationError, DataError

__all__ = ["HOLDS", "check_hold", "uniform_step"]

#: How the input moves between two samples: ``"foh"`` (first-order hold, linear: the default) or ``"zoh"``
#: (zero-order hold, constant until the next sample).
HOLDS = ("foh", "zoh")


def check_hold(hold: str) -> str:
    """``hold`` itself; a ``ValueError`` naming the choices if it is not one of :data:`HOLDS`."""
    if hold not in HOLDS:
        raise ConfigurationError(f"hold must be 'foh' (the input linear between samples) or 'zoh' (held constant until the "
                         f"next sample), got {hold!r}")
    return hold


def uniform_step(t: torch.Tensor, rtol: float = 1e-6) -> float:
    """The sampling interval of a uniform grid ``t`` (time,); raises :class:`DataError` if not uniform."""
    if t.dim() != 1 or len(t) < 2:
        raise DataError(f"time must be a 1-D tensor of at least 2 samples, got shape {tuple(t.shape)}")
    dt = torch.diff(t)
    h = float(dt.mean())
    if not bool(torch.all(dt > 0)):
        raise DataError("time must be strictly increasing; sort the samples and drop duplicates")
    if float((dt - h).abs().max()) > rtol * h:
        raise DataError(
            f"uniform sampling is required here, but the time steps range from {float(dt.min()):.6g} to "
            f"{float(dt.max()):.6g} s; resample onto a uniform grid, or simulate with solver=RK4() or Dopri5()"
        )
    return h
