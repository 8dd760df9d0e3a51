r"""Error measures. The paper's *mismatch norm* is $\mathrm{RMS}(y - \hat y)/\mathrm{RMS}(y)$ (a fraction)."""

from __future__ import annotations

import torch

__all__ = ["mismatch", "fit_percent", "rmse"]


def mismatch(y: torch.Tensor, y_model: torch.Tensor) -> float:
    r"""$\|y - \hat y\|_2 / \|y\|_2$ over all samples (equals NRMSE normalised by RMS(y)); a fraction."""
    y, y_model = y.detach(), y_model.detach()
    return float(torch.linalg.vector_norm(y - y_model) / torch.linalg.vector_norm(y))


def fit_percent(y: torch.Tensor, y_model: torch.Tensor) -> float:
    r"""MATLAB-style fit, $100\,(1 - \|y - \hat y\| / \|y - \bar y\|)$ in %."""
    y, y_model = y.detach(), y_model.detach()
    return float(100 * (1 - torch.linalg.vector_norm(y - y_model) / torch.linalg.vector_norm(y - y.mean())))


def rmse(y: torch.Tensor, y_model: torch.Tensor) -> float:
    """Root-mean-square error in the data's units."""
    return float(torch.sqrt(torch.mean((y.detach() - y_model.detach()) ** 2)))
