r"""Stage 2: the residual fitted to $y - \hat y$ with the physics frozen.

For the Chebyshev-Hammerstein residual, $r = \Psi(\rho)\,c$ is linear in the numerator and direct
coefficients $c$ for fixed poles $\rho$, so it is fitted by variable projection (Golub-Pereyra):

$$ \min_\rho \frac{\|e - \Psi(\rho)\, c(\rho)\|^2}{\|e\|^2}, \qquad
   c(\rho) = \arg\min_c \|e - \Psi c\|^2 + \lambda \|D^{-1} c\|^2, $$

with $e = y - \hat y$ and the columns of $\Psi$ scaled to unit norm by $D$ ($A = \Psi D$). $c$ solves the
ridge's normal equations $(A^\top A + \lambda I)\,D^{-1}c = A^\top e$, $\lambda = 10^{-8}$, by Cholesky:
on a single sine the regressors are rank-deficient (each harmonic spans two dimensions at steady
state, but the filter gives it ``order`` columns), and without the ridge the least-squares solution
and its gradient are dominated by round-off, so L-BFGS stalls at different points from different
starts. With unit-norm columns the ridge bounds the condition number of $A^\top A + \lambda I$ by
$k/\lambda$ ($k$ columns, a few tens: below $10^{10}$, far inside float64), and changes the fit by
$O(\lambda)$. The $k \times k$ Gram matrix is one pass over the $N \times k$ regressors: at 100 000
samples the projection takes 0.036 s, the QR factorisation of $[A;\ \sqrt\lambda I]$ with its $Q$ 0.131 s.
L-BFGS runs over the handful of pole parameters $\rho$ (gradients through the Cholesky solve and the exact
LTI simulation). Other residuals (the MLP baselines) are fitted by gradient descent.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from torchpaml._budget import Budget, OverBudget
from torchpaml._fit.output_error import minimize_output_error
from torchpaml._metrics import mismatch
from torchpaml._residual.chebyshev_hammerstein import ChebyshevHammerstein

__all__ = ["ResidualEstimate", "fit_chebyshev_hammerstein", "fit_residual", "project"]

log = logging.getLogger(__name__)


@dataclass
class ResidualEstimate:
    """Result of a stage-2 fit: the share of the target the residual leaves unexplained, ‖e − r‖/‖e‖."""

    unexplained: float
    iterations: int
    method: str


RIDGE = 1e-8
#: The pole search stops when a step changes the squared mismatch by less than this share of it: the unexplained
#: share then moves in its ninth digit (measured on 20 000 samples), and the search takes half the evaluations
#: that an absolute tolerance of 1e-14 does.
CHANGE_TOLERANCE = 1e-9


def project(regressors: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Ridge least-squares coefficients (n, m + 1) and fitted values (module docstring).

    regressors (batch, time, n, m + 1), target (batch, time) -> coefficients (n, m + 1), fit (batch, time).
    """
    n, width = regressors.shape[-2:]
    M = regressors.reshape(-1, n * width)
    scale = torch.linalg.vector_norm(M.detach(), dim=0).clamp(min=1e-300)
    A = M / scale
    gram = A.T @ A + RIDGE * torch.eye(n * width, dtype=M.dtype)
    scaled = torch.cholesky_solve(A.T @ target.reshape(-1, 1), torch.linalg.cholesky(gram))
    return (scaled[:, 0] / scale).reshape(n, width), (A @ scaled).reshape(target.shape)


def joined_in_time(parts: torch.Tensor | Sequence[torch.Tensor]) -> torch.Tensor:
    """A batch as it is, or records of unequal length (1, time_i, ...) joined in time, (1, Σ time_i, ...): the
    samples a least squares or a mismatch counts."""
    return parts if isinstance(parts, torch.Tensor) else torch.cat(list(parts), dim=1)


def per_record(method, t, u) -> torch.Tensor:
    """``method(t, u)`` of one batch, or of each record (each filter from rest) joined in time."""
    if isinstance(t, torch.Tensor):
        return method(t, u)
    return joined_in_time([method(t_i, u_i) for t_i, u_i in zip(t, u, strict=True)])


def fit_chebyshev_hammerstein(
    residual: ChebyshevHammerstein,
    t: torch.Tensor | Sequence[torch.Tensor],
    u: torch.Tensor | Sequence[torch.Tensor],
    target: torch.Tensor | Sequence[torch.Tensor],
    *,
    max_iter: int = 100,
    rtol: float = CHANGE_TOLERANCE,
    budget: Budget | None = None,
) -> ResidualEstimate:
    """Fit ``residual`` in place to ``target`` = y − ŷ, (batch, time, outputs), by variable projection; the pole search
    stops when a step changes the squared mismatch by less than ``rtol`` of it (:data:`CHANGE_TOLERANCE`), or over
    ``budget`` (a :class:`~torchpaml.Budget`: progress lines, and its limit), with the best coefficients for the poles
    it reached.

    Records of unequal length come as sequences, one ``t`` (time_i,), ``u`` (1, time_i, n_u) and ``target``
    (1, time_i, outputs) per record: each record's filter starts from rest, and one least squares takes every
    sample (for records of one length, the same rows as their batch). With several outputs each has its own
    numerators, projected on its own target divided by that target's norm, so that every output weighs the same in
    the pole search (the coefficients are then scaled back)."""
    poles = residual.pole_parameters()
    target = joined_in_time(target)
    scales = torch.linalg.vector_norm(target.detach().reshape(-1, target.shape[-1]), dim=0).clamp(min=1e-300)
    scaled = target if residual.outputs == 1 else target / scales

    def projections() -> list[tuple[torch.Tensor, torch.Tensor]]:
        regressors = per_record(residual.regressors, t, u)
        return [project(regressors, scaled[..., o]) for o in range(residual.outputs)]

    def projected():
        return torch.stack([fitted for _, fitted in projections()], dim=-1)

    try:
        _, iterations = minimize_output_error(projected, scaled, poles, max_iter=max_iter, rtol=rtol, budget=budget)
    except OverBudget as over:  # the coefficients below are the best for the poles where the search stood
        log.info("%s; the residual keeps the poles it reached", over)
        iterations = max_iter
    with torch.no_grad():
        coefficients = [c for c, _ in projections()]
        residual.set_coefficients(coefficients[0] if residual.outputs == 1 else
                                  torch.stack(coefficients) * scales[:, None, None])
        unexplained = mismatch(target, per_record(residual, t, u))
    return ResidualEstimate(unexplained, iterations, "variable-projection")


def fit_residual(
    residual: torch.nn.Module,
    t: torch.Tensor,
    u: torch.Tensor,
    y_physics: torch.Tensor,
    target: torch.Tensor,
    *,
    steps: int = 2000,
    lr: float = 3e-3,
) -> ResidualEstimate:
    """Fit any output residual in place to ``target`` = y − ŷ by Adam (the MLP baseline)."""
    params = [p for p in residual.parameters() if p.requires_grad]
    y_physics = y_physics.detach()
    _, iterations = minimize_output_error(
        lambda: residual(t, u, y_physics), target, params, optimizer="adam", max_iter=steps, lr=lr
    )
    with torch.no_grad():
        unexplained = mismatch(target, residual(t, u, y_physics))
    return ResidualEstimate(unexplained, iterations, "adam")
