"""The check that every simulated output passes: finite and within a bound."""

from __future__ import annotations

import torch

from torchpaml._errors import SimulationError

__all__ = ["BLOWUP", "blown_up", "checked_output"]

#: The bound on a simulated output's magnitude, beyond which the simulation counts as blown up.
BLOWUP = 1e8


def blown_up(y: torch.Tensor, blowup: float = BLOWUP) -> torch.Tensor:
    """Where ``y`` is non-finite or beyond ``blowup`` in magnitude (a boolean tensor of ``y``'s shape)."""
    return ~torch.isfinite(y) | (y.abs() > blowup)


def checked_output(y: torch.Tensor, t: torch.Tensor, blowup: float = BLOWUP) -> torch.Tensor:
    """``y`` (batch, time, n_output) itself; raises :class:`~torchpaml.SimulationError` naming the time where it is
    non-finite or beyond ``blowup``."""
    bad = blown_up(y, blowup)
    if bool(bad.any()):
        k = int(bad.any(dim=0).any(dim=-1).nonzero()[0])
        raise SimulationError(
            f"the simulated output blew up (non-finite or |y| > {blowup:g}) at t = {float(t[k]):.4g} s; the "
            "parameters are probably unstable or unphysical (e.g. negative damping, wrong sign of stiffness), "
            "or the input is far larger than the physics is meant for"
        )
    return y
