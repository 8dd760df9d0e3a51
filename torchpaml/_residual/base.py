"""The interface every output residual implements."""

from __future__ import annotations

import torch
from torch import nn

from torchpaml._arguments import Rebuildable

__all__ = ["AbstractResidual"]


class AbstractResidual(Rebuildable, nn.Module):
    r"""An output residual $r = \mathcal R^\gamma[u]$, added to the physics output: $y \approx \hat y + r$.

    ``forward(t, u, y_physics)`` maps t (time,), u (batch, time, n_u) and the physics output
    y_physics (batch, time, n_y) to r (batch, time, n_y). Residuals that depend on u alone (the
    Chebyshev-Hammerstein model) ignore ``y_physics``.

    Attributes:
        alpha: the input amplitude the residual is built for (the Chebyshev domain $|u| \le \alpha$); ``None`` for
            a residual without one (the MLP).
    """

    alpha: float | None = None

    def forward(self, t: torch.Tensor, u: torch.Tensor, y_physics: torch.Tensor | None = None) -> torch.Tensor:
        raise NotImplementedError(f"{type(self).__name__} must implement forward(t, u, y_physics)")
