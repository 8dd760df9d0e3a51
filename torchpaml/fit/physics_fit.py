r"""Stage 1: the prediction error method for the physical parameters.

$\hat\theta = \arg\min_\theta \|y - \mathcal H^\theta[u]\|^2$ (output error: the simulated, not the
one-step-ahead, output). One learnable parameter with ``bounds``: Brent's bounded scalar
minimiser (``scipy.optimize.minimize_scalar``), as in the paper. Several: L-BFGS on the
unconstrained parametrisation with gradients through the simulator.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from scipy.optimize import minimize_scalar

from torchpaml.fit.output_error import minimize_output_error
from torchpaml.metrics import mismatch

__all__ = ["PhysicsEstimate", "fit_physics"]


@dataclass
class PhysicsEstimate:
    """Result of :func:`fit_physics`: parameters in physical units and the final mismatch (fraction)."""

    parameters: dict[str, float]
    mismatch: float
    iterations: int
    method: str


def fit_physics(
    physics,
    t: torch.Tensor,
    u: torch.Tensor,
    y: torch.Tensor,
    *,
    bounds: tuple[float, float] | None = None,
    max_iter: int = 200,
    xatol: float = 1e-8,
    **simulate_options,
) -> PhysicsEstimate:
    """Fit the learnable physical parameters of ``physics`` in place to (u, y) of shape (batch, time, ch).

    Args:
        bounds: search interval for a single learnable parameter (bounded scalar minimisation).
        max_iter: L-BFGS iterations (several parameters).
        xatol: absolute tolerance of the bounded scalar search.
        simulate_options: forwarded to :func:`~torchpaml.simulate.simulate` (method, rtol, knots...).
    """
    names = physics.learnable_names()
    if not names:
        raise ValueError(f"{physics.display_name} has no learnable parameter; call set_learnable(name) first")
    if bounds is not None:
        if len(names) != 1:
            raise ValueError(f"bounds apply to one learnable parameter, but {names} are learnable")
        lower, upper = bounds
        scale = float(torch.sum(y**2))

        def loss(value: float) -> float:
            physics.assign(**{names[0]: value})
            with torch.no_grad():
                return float(torch.sum((y - physics(t, u, **simulate_options)) ** 2)) / scale

        result = minimize_scalar(loss, bounds=(lower, upper), method="bounded", options={"xatol": xatol})
        physics.assign(**{names[0]: float(result.x)})
        iterations, method = int(result.nfev), "bounded-scalar"
    else:
        params = [p for p in physics.parameters() if p.requires_grad]
        _, iterations = minimize_output_error(lambda: physics(t, u, **simulate_options), y, params, max_iter=max_iter)
        method = "lbfgs"
    with torch.no_grad():
        final = mismatch(y, physics(t, u, **simulate_options))
    values = physics.physical_parameters()
    return PhysicsEstimate({n: values[n] for n in names}, final, iterations, method)
