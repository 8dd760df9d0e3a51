r"""Stage 2: the residual fitted to $y - \hat y$ with the physics frozen.

For the Chebyshev-Hammerstein residual, $r = \Psi(\rho)\,c$ is linear in the numerator and direct
coefficients $c$ for fixed poles $\rho$, so it is fitted by variable projection (Golub-Pereyra):

$$ \min_\rho \frac{\|e - P_{\Psi(\rho)}\, e\|^2}{\|e\|^2}, \qquad P_\Psi = QQ^\top,\ \Psi D = QR, $$

with $e = y - \hat y$, columns scaled by $D$ for conditioning, L-BFGS over the handful of pole
parameters $\rho$ (gradients through the QR and the exact LTI simulation), then
$c = D R^{-1} Q^\top e$. Other residuals (the MLP baselines) are fitted by gradient descent.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from torchpaml.fit.output_error import minimize_output_error
from torchpaml.metrics import mismatch
from torchpaml.residual.chebyshev_hammerstein import ChebyshevHammerstein

__all__ = ["ResidualFit", "fit_chebyshev_hammerstein", "fit_residual"]


@dataclass
class ResidualFit:
    """Result of a stage-2 fit: the share of the target the residual leaves unexplained, ‖e − r‖/‖e‖."""

    unexplained: float
    iterations: int
    method: str


def _projection(regressors: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Least-squares coefficients (n, m + 1) and the fitted values, via column-scaled QR."""
    n, width = regressors.shape[-2:]
    M = regressors.reshape(-1, n * width)
    scale = torch.linalg.vector_norm(M.detach(), dim=0).clamp(min=1e-300)
    Q, R = torch.linalg.qr(M / scale)
    e = target.reshape(-1, 1)
    qe = Q.T @ e
    coefficients = torch.linalg.solve_triangular(R, qe, upper=True)[:, 0] / scale
    return coefficients.reshape(n, width), (Q @ qe).reshape(target.shape)


def fit_chebyshev_hammerstein(
    residual: ChebyshevHammerstein,
    t: torch.Tensor,
    u: torch.Tensor,
    target: torch.Tensor,
    *,
    max_iter: int = 100,
) -> ResidualFit:
    """Fit ``residual`` in place to ``target`` = y − ŷ, (batch, time, 1), by variable projection."""
    poles = residual.pole_parameters()

    def projected():
        return _projection(residual.regressors(t, u), target[..., 0])[1][..., None]

    _, iterations = minimize_output_error(projected, target, poles, max_iter=max_iter)
    with torch.no_grad():
        coefficients, _ = _projection(residual.regressors(t, u), target[..., 0])
        residual.set_coefficients(coefficients)
        unexplained = mismatch(target, residual(t, u))
    return ResidualFit(unexplained, iterations, "variable-projection")


def fit_residual(
    residual: torch.nn.Module,
    t: torch.Tensor,
    u: torch.Tensor,
    y_physics: torch.Tensor,
    target: torch.Tensor,
    *,
    steps: int = 2000,
    lr: float = 3e-3,
) -> ResidualFit:
    """Fit any output residual in place to ``target`` = y − ŷ by Adam (the MLP baseline)."""
    params = [p for p in residual.parameters() if p.requires_grad]
    y_physics = y_physics.detach()
    _, iterations = minimize_output_error(
        lambda: residual(t, u, y_physics), target, params, optimizer="adam", max_iter=steps, lr=lr
    )
    with torch.no_grad():
        unexplained = mismatch(target, residual(t, u, y_physics))
    return ResidualFit(unexplained, iterations, "adam")
