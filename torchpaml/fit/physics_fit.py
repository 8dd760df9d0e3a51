r"""The one physics fit: output error by a trust-region method, with forward-mode Jacobians.

$$ \hat\rho = \arg\min_\rho \tfrac12 \|r(\rho)\|^2, \qquad r = \frac{y - \mathcal H^{\theta(\rho)}[u]}{\|y\|} $$

over the raw (unconstrained) values $\rho$ of the learnable physical parameters $\theta$, all records
stacked. ``scipy.optimize.least_squares`` (``method="trf"``) solves it; its Jacobian
$\partial r/\partial\rho$ comes from :func:`~torchpaml.simulate.output_jacobian` (exact path for linear
physics, the parallel RK4 engine otherwise: one Newton solve and one sweep per parameter).

**Bounds** are the one bound mechanism: ``bounds={name: (lower, upper)}`` in physical units become
closed bounds on $\rho$ through the parameter's own constraint map (monotone, so the interval maps to
an interval), and the trust region keeps every iterate strictly inside. An optimum beyond a bound
ends within about 1e-9 of it (the paper's $\zeta$ capped at 5 for $\alpha = 10$).

Trial steps whose simulation blows up are rejected by the trust region (their residual is inf);
a start that blows up raises :class:`~torchpaml.errors.SimulationError`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from scipy.optimize import least_squares

from torchpaml.data import Experiment
from torchpaml.errors import SimulationError
from torchpaml.simulate.sensitivity import output_jacobian, raw_parameters

__all__ = ["PhysicsEstimate", "fit_physics"]


@dataclass
class PhysicsEstimate:
    """Result of :func:`fit_physics`.

    Attributes:
        parameters: fitted learnable parameters in physical units.
        mismatch: $\\|y - \\hat y\\| / \\|y\\|$ over all records (a fraction).
        residual: $r = (y - \\hat y)/\\|y\\|$ at the optimum, all records concatenated, (samples,).
        jacobian: $\\partial r / \\partial\\rho$ at the optimum, (samples, p), columns in the order of ``parameters``.
        evaluations: number of simulations (a Jacobian counts as one).
    """

    parameters: dict[str, float]
    mismatch: float
    residual: torch.Tensor
    jacobian: torch.Tensor
    evaluations: int


def _raw_bounds(physics, names: list[str], bounds: dict[str, tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    lower, upper = np.full(len(names), -np.inf), np.full(len(names), np.inf)
    unknown = sorted(set(bounds) - set(names))
    if unknown:
        raise ValueError(f"bounds name parameter(s) {unknown} that are not learnable; learnable: {names}")
    for i, name in enumerate(names):
        if name not in bounds:
            continue
        lo, hi = (float(b) for b in bounds[name])
        if not lo < hi:
            raise ValueError(f"bounds for {name!r} need lower < upper, got ({lo}, {hi})")
        owner, leaf = physics._owner(name)
        constraint = getattr(owner.parametrizations, leaf)[0]
        value = float(getattr(owner, leaf).detach())
        if not lo <= value <= hi:
            raise ValueError(f"{name} = {value:g} starts outside its bounds ({lo:g}, {hi:g}); assign a start inside")
        with torch.no_grad():
            ends = constraint.right_inverse(torch.tensor([lo, hi], dtype=torch.float64)).nan_to_num(-np.inf, np.inf, -np.inf)
        lower[i], upper[i] = float(ends[0]), float(ends[1])
    return lower, upper


def fit_physics(
    physics,
    records: Experiment | Sequence[Experiment],
    *,
    bounds: dict[str, tuple[float, float]] | None = None,
    max_nfev: int = 60,
    **simulate_options,
) -> PhysicsEstimate:
    """Fit the learnable physical parameters of ``physics`` in place to the records (module docstring).

    Args:
        physics: the model; its learnable parameters are fitted, the others stay fixed.
        records: one or more :class:`~torchpaml.data.Experiment`, each simulated from rest.
        bounds: ``{name: (lower, upper)}`` in physical units.
        max_nfev: iteration limit of the trust region.
        simulate_options: ``substeps``/``segment`` of the RK4 engine.
    """
    records = [records] if isinstance(records, Experiment) else list(records)
    names = physics.learnable_names()
    if not names:
        raise ValueError(f"{physics.display_name} has no learnable parameter; call set_learnable(name) first")
    lower, upper = _raw_bounds(physics, names, bounds or {})
    raw = list(raw_parameters(physics, names).values())
    targets = [r.y[None] for r in records]
    scale = float(torch.sqrt(sum(torch.sum(y**2) for y in targets)))
    count = {"simulations": 0}
    memo: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
    warm = [{} for _ in records]  # each record's last solution starts the next Newton solve

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual (samples,) and Jacobian (samples, p) at raw values ``x``, once per point."""
        key = x.tobytes()
        if key not in memo:
            count["simulations"] += 1
            with torch.no_grad():
                for tensor, value in zip(raw, x, strict=True):
                    tensor.copy_(torch.tensor(value, dtype=torch.float64))
            parts = [output_jacobian(physics, names, r.t - r.t[0], r.u[None], warm=w, **simulate_options)
                     for r, w in zip(records, warm, strict=True)]
            residual = torch.cat([(y - y_hat).flatten() for y, (y_hat, _) in zip(targets, parts, strict=True)]) / scale
            jacobian = -torch.cat([J.reshape(-1, len(names)) for _, J in parts]) / scale
            memo.clear()
            memo[key] = residual.numpy(), jacobian.numpy()
        return memo[key]

    def fun(x: np.ndarray) -> np.ndarray:
        try:
            return evaluate(x)[0]
        except SimulationError:
            return np.full(sum(y.numel() for y in targets), np.inf)

    start = np.clip(torch.stack([v.detach() for v in raw]).numpy(), lower, upper)
    evaluate(start)  # raises SimulationError, naming the blow-up, at a bad start
    result = least_squares(fun, start, jac=lambda x: evaluate(x)[1], bounds=(lower, upper), method="trf",
                           x_scale="jac", max_nfev=max_nfev, ftol=1e-10, xtol=1e-10, gtol=1e-10)
    residual, jacobian = evaluate(result.x)
    values = physics.physical_parameters()
    residual = torch.from_numpy(residual.copy())
    return PhysicsEstimate({n: values[n] for n in names}, float(torch.linalg.vector_norm(residual)), residual,
                           torch.from_numpy(jacobian.copy()), count["simulations"])
