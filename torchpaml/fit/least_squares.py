r"""Output-error fitting by a trust-region Levenberg-Marquardt method with batched Jacobians.

The refits of the missing-effect search solve small nonlinear least-squares problems
$\min_\rho \tfrac12\|r(\rho)\|^2$, $r = (y - \mathcal H^{\theta(\rho)}[u]) / \|y\|$, over the raw
(unconstrained) parameters $\rho$ of a few physical parameters $\theta$. They are solved by
``scipy.optimize.least_squares`` (``method="trf"``, a trust-region Levenberg-Marquardt variant
that converges in a handful of Jacobians). The Jacobian is a central difference

$$ J_{:,j} = \frac{r(\rho + h_j e_j) - r(\rho - h_j e_j)}{2 h_j}, \qquad h_j = 10^{-5}\max(1, |\rho_j|), $$

computed in **one** batched simulation: each of the $2p$ perturbed parameter sets is a batch row
(:func:`simulate_rows`), and a small ODE costs the same for 1 or 20 rows because its cost is the
per-step overhead. Nonlinear physics is integrated by fixed-step RK4 on the sample grid
(``method="rk4"``), so the output is a smooth function of $\rho$ and the differences are exact to
$O(h^2)$; adaptive step control would make it piecewise smooth. Linear physics keeps the exact
discretisation (one cheap simulation per row).

Rows are batched for :class:`~torchpaml.physics.SecondOrderPhysics` (composed models included),
whose accelerations, forces and maps see position, velocity and input as (rows,) signals, so a
parameter batched to shape (rows,) broadcasts elementwise, as in every library model and effect.
Other physics (a state of shape (rows, n_state) would not broadcast) is simulated row by row.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from scipy.optimize import least_squares
from torch.func import functional_call

from torchpaml.data import Experiment
from torchpaml.errors import SimulationError
from torchpaml.physics.base import SecondOrderPhysics

__all__ = ["LeastSquaresFit", "fit_least_squares", "raw_parameters", "simulate_record", "simulate_rows"]

NONLINEAR_METHOD = "rk4"


@dataclass
class LeastSquaresFit:
    """Result of :func:`fit_least_squares`.

    Attributes:
        parameters: fitted learnable parameters in physical units.
        mismatch: $\\|y - \\hat y\\| / \\|y\\|$ over all records (a fraction).
        residual: $r = (y - \\hat y)/\\|y\\|$ at the optimum, all records concatenated, (samples,).
        jacobian: $\\partial r / \\partial\\rho = -\\partial \\hat y / \\partial\\rho \\,/\\, \\|y\\|$ at the optimum,
            (samples, p), columns in the order of ``parameters``.
        evaluations: number of simulations of the model (Jacobians count their rows as one).
    """

    parameters: dict[str, float]
    mismatch: float
    residual: torch.Tensor
    jacobian: torch.Tensor
    evaluations: int


def raw_parameters(physics, names: Sequence[str]) -> dict[str, torch.Tensor]:
    """``{functional_call key: raw tensor}`` for the physical parameters ``names`` (their unconstrained originals)."""
    keys = {id(p): key for key, p in physics.named_parameters()}
    raw = {}
    for name in names:
        owner, leaf = physics._owner(name)
        original = getattr(owner.parametrizations, leaf).original
        raw[keys[id(original)]] = original
    return raw


def simulate_rows(physics, names: Sequence[str], rows: torch.Tensor, t: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    """Outputs for several raw parameter sets at once.

    Args:
        physics: the model; its other parameters keep their values.
        names: physical parameter names, length p.
        rows: raw (unconstrained) values, shape (rows, p).
        t: (time,); u: input of one record, (1, time, n_input).

    Returns:
        y: (rows, time, n_output). Raises :class:`SimulationError` if any row blows up.
    """
    keys = list(raw_parameters(physics, names))
    linear = physics.state_space() is not None
    options = {} if linear else {"method": NONLINEAR_METHOD}
    if linear or not isinstance(physics, SecondOrderPhysics):
        return torch.cat([functional_call(physics, dict(zip(keys, row, strict=True)), (t, u), options) for row in rows])
    batched = dict(zip(keys, rows.T, strict=True))
    return functional_call(physics, batched, (t, u.expand(len(rows), -1, -1)), options)


def simulate_record(physics, record: Experiment) -> torch.Tensor:
    """The model's output on one record, (1, time, n_output), by the same simulator the fit uses."""
    method = "auto" if physics.state_space() is not None else NONLINEAR_METHOD
    with torch.no_grad():
        return physics(record.t - record.t[0], record.u[None], method=method)


def fit_least_squares(physics, experiments: Experiment | Sequence[Experiment], *, max_nfev: int = 60) -> LeastSquaresFit:
    """Fit the learnable physical parameters of ``physics`` in place to the records (module docstring).

    Raises :class:`SimulationError` if the model blows up at its starting parameters; trial steps that
    blow up are rejected by the trust region instead.
    """
    records = [experiments] if isinstance(experiments, Experiment) else list(experiments)
    names = physics.learnable_names()
    if not names:
        raise ValueError(f"{physics.display_name} has no learnable parameter; call set_learnable(name) first")
    raw = raw_parameters(physics, names)
    targets = [r.y[None] for r in records]
    scale = float(torch.sqrt(sum(torch.sum(y**2) for y in targets)))
    count = {"simulations": 0}

    def residuals(rows: torch.Tensor) -> torch.Tensor:
        """(rows, samples): r for each raw parameter set."""
        count["simulations"] += 1
        with torch.no_grad():
            parts = [(y - simulate_rows(physics, names, rows, r.t - r.t[0], r.u[None])).flatten(1)
                     for r, y in zip(records, targets, strict=True)]
        return torch.cat(parts, dim=1) / scale

    def fun(x: np.ndarray) -> np.ndarray:
        try:
            return residuals(torch.from_numpy(x)[None])[0].numpy()
        except SimulationError:
            return np.full(sum(y.numel() for y in targets), np.inf)

    def jac(x: np.ndarray) -> np.ndarray:
        center = torch.from_numpy(x)
        step = 1e-5 * center.abs().clamp(min=1.0)
        shifts = torch.diag(step)
        r = residuals(torch.cat([center + shifts, center - shifts]))
        p = len(x)
        return ((r[:p] - r[p:]) / (2 * step[:, None])).T.numpy()

    start = torch.cat([v.detach().reshape(1) for v in raw.values()]).numpy()
    residuals(torch.from_numpy(start)[None])  # raises SimulationError, naming the blow-up, at a bad start
    result = least_squares(fun, start, jac=jac, method="trf", x_scale="jac", max_nfev=max_nfev,
                           ftol=1e-8, xtol=1e-8, gtol=1e-8)
    with torch.no_grad():
        for tensor, value in zip(raw.values(), result.x, strict=True):
            tensor.copy_(torch.tensor(value, dtype=torch.float64))
    residual = torch.from_numpy(result.fun)
    values = physics.physical_parameters()
    return LeastSquaresFit({n: values[n] for n in names}, float(torch.linalg.vector_norm(residual)), residual,
                           torch.from_numpy(result.jac), count["simulations"])
