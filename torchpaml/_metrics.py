r"""Error measures. The paper's *mismatch norm* is $\mathrm{RMS}(y - \hat y)/\mathrm{RMS}(y)$ (a fraction).

With several output channels (the last axis), each has its own, $m_c = \|y_c - \hat y_c\|_2 / \|y_c\|_2$
(:func:`channel_mismatch`), and the overall mismatch is their root mean square,
$m = \sqrt{\tfrac1C \sum_c m_c^2}$ (:func:`mismatch`): every channel weighs the same, whatever its unit. A fit
minimises exactly $m^2$ on its training records, its residual divided by :func:`channel_scales`.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

__all__ = ["channel_mismatch", "channel_scales", "channel_weights", "fit_percent", "mismatch", "rmse", "sample_scales"]


def channel_mismatch(y: torch.Tensor, y_model: torch.Tensor) -> torch.Tensor:
    r"""$m_c = \|y_c - \hat y_c\|_2 / \|y_c\|_2$ of each output channel $c$ (the last axis) over all samples: (C,)."""
    width = y.shape[-1]
    error, y = (y.detach() - y_model.detach()).reshape(-1, width), y.detach().reshape(-1, width)
    return torch.linalg.vector_norm(error, dim=0) / torch.linalg.vector_norm(y, dim=0)


def mismatch(y: torch.Tensor, y_model: torch.Tensor) -> float:
    r"""The mismatch, a fraction: $\|y - \hat y\|_2 / \|y\|_2$ over all samples for one output channel (equals NRMSE
    normalised by RMS(y)); for several (the last axis), the root mean square of :func:`channel_mismatch`."""
    if y.dim() > 1 and y.shape[-1] > 1:
        return float(channel_mismatch(y, y_model).square().mean().sqrt())
    y, y_model = y.detach(), y_model.detach()
    return float(torch.linalg.vector_norm(y - y_model) / torch.linalg.vector_norm(y))


def channel_scales(outputs: Sequence[torch.Tensor]) -> torch.Tensor:
    r"""The scale $s_c$ of each output channel over the records' ``outputs`` (each (..., C)): a fit divides its
    residual by it, $s_c = \sqrt{C \sum y_c^2}$, so that its squared norm is the squared :func:`mismatch`,
    $\tfrac1C \sum_c \|y_c - \hat y_c\|^2 / \|y_c\|^2$. One channel: $\|y\|$. Returns (C,)."""
    width = outputs[0].shape[-1]
    if width == 1:
        return torch.sqrt(sum(torch.sum(y.detach() ** 2) for y in outputs)).reshape(1)
    return torch.sqrt(width * sum(y.detach().reshape(-1, width).square().sum(dim=0) for y in outputs))


def channel_weights(outputs: Sequence[torch.Tensor]) -> torch.Tensor:
    """Weights (C,) that put the output channels of the records' ``outputs`` (each (..., C)) on one scale in a loss or
    a regression over all channels: $1/\\mathrm{RMS}(y_c)$, and exactly 1 for one channel (its numbers unchanged)."""
    width = outputs[0].shape[-1]
    if width == 1:
        return torch.ones(1, dtype=torch.float64)
    return (width * sum(y.numel() // width for y in outputs)) ** 0.5 / channel_scales(outputs)


def sample_scales(outputs: Sequence[torch.Tensor]) -> torch.Tensor:
    """:func:`channel_scales` for every sample of the records' ``outputs`` flattened and joined, as a fit's residual
    lays them out (time-major, channels fastest): (Σ numel,)."""
    scales = channel_scales(outputs)
    return torch.cat([scales.repeat(y.numel() // len(scales)) for y in outputs])


def fit_percent(y: torch.Tensor, y_model: torch.Tensor) -> float:
    r"""MATLAB-style fit, $100\,(1 - \|y - \hat y\| / \|y - \bar y\|)$ in %."""
    y, y_model = y.detach(), y_model.detach()
    return float(100 * (1 - torch.linalg.vector_norm(y - y_model) / torch.linalg.vector_norm(y - y.mean())))


def rmse(y: torch.Tensor, y_model: torch.Tensor) -> float:
    """Root-mean-square error in the data's units."""
    return float(torch.sqrt(torch.mean((y.detach() - y_model.detach()) ** 2)))
