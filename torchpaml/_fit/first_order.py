r"""The first-order check of the paper: re-estimate $\theta$ on $y - r$ and report $\Delta\theta$.

If the residual class is first-order incompatible with the physics on the input
($\langle \mathcal R^\gamma[u], \partial_\theta \mathcal H^\theta[u]\rangle = 0$), the re-estimate equals the
physics-only estimate up to finite-horizon effects (Thm. 2 of the paper).
"""

from __future__ import annotations

import copy

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._data import Record

from torchpaml._fit.physics_fit import fit_physics

__all__ = ["reestimate_shift"]


def reestimate_shift(physics: AbstractPhysics, residual, t, u, y, **fit_options) -> dict[str, float]:
    r"""$\{\theta: \hat\theta(y - r) - \hat\theta(y)\}$ for the learnable parameters; ``physics`` is left as it is.

    ``residual`` is either a module that depends on u alone (``residual(t, u)``, as the
    Chebyshev-Hammerstein model does) or the residual's output r itself, a tensor shaped like y
    (for residuals that also read the physics output, evaluate them at the current $\hat y$).
    t (time,), u and y (batch, time, ch); ``fit_options`` are those of :func:`~torchpaml.fit_physics`
    (e.g. ``bounds``).
    """
    before = {n: v for n, v in physics.physical_parameters().items() if n in physics.learnable_names()}
    with torch.no_grad():
        compensated = y - (residual if isinstance(residual, torch.Tensor) else residual(t, u))
    refit = copy.deepcopy(physics)
    after = fit_physics(refit, Record.records(t, u, compensated), **fit_options).parameters
    return {name: after[name] - before[name] for name in before}
