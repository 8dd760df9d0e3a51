r"""Differentiable IIR filtering along time, with ``scipy.signal.lfilter`` for every recursion.

Per channel $c$ the filter is the difference equation (zero initial conditions)

$$ y_t + \sum_{i=1}^{n_a} a_{c,i}\, y_{t-i} = \sum_{j=0}^{n_b-1} b_{c,j}\, x_{t-j}, $$

i.e. $y = \frac{B_c(q)}{A_c(q)} x$ with $A_c$ monic. No Python loop runs over samples: the
recursion is scipy's compiled direct form II transposed, batched over the batch axis.

Backward pass (adjoint filtering). With $g = \partial L/\partial y$ and
$\tilde g = \mathrm{flip}(A^{-1}\mathrm{flip}(g))$ (the anti-causal filter $1/A$):

$$ \frac{\partial L}{\partial x_t} = \sum_j b_j \tilde g_{t+j}, \qquad
   \frac{\partial L}{\partial b_j} = \sum_t \tilde g_t\, x_{t-j}, \qquad
   \frac{\partial L}{\partial a_i} = -\sum_t \tilde g_t\, y_{t-i}. $$

Forward mode: $\dot y = A^{-1}\big(B \dot x + \dot B x - \dot A y\big)$.
"""

from __future__ import annotations

import numpy as np
import torch

from torchpaml._errors import ConfigurationError
from scipy import signal

__all__ = ["iir_filter"]


def _lfilter(b: np.ndarray, a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Per-channel ``lfilter``: b (C, nb), a (C, na) monic without the leading 1, x (B, T, C)."""
    out = np.empty_like(x)
    for c in range(x.shape[-1]):
        out[..., c] = signal.lfilter(b[c], np.concatenate(([1.0], a[c])), x[..., c], axis=-1)
    return out


def _lagged_products(g: np.ndarray, s: np.ndarray, lags: int) -> np.ndarray:
    """(C, lags) array of $\\sum_{batch,t} g_t s_{t-j}$ for j = 0..lags-1; g, s (B, T, C)."""
    T = g.shape[1]
    out = np.zeros((g.shape[-1], lags))
    for j in range(min(lags, T)):
        out[:, j] = np.einsum("btc,btc->c", g[:, j:], s[:, : T - j])
    return out


def _numpy(t: torch.Tensor) -> np.ndarray:
    return t.detach().cpu().numpy()


class _IIRFilter(torch.autograd.Function):
    @staticmethod
    def forward(x, b, a):
        y = _lfilter(_numpy(b), _numpy(a), _numpy(x))
        return torch.from_numpy(y).to(device=x.device, dtype=x.dtype)

    @staticmethod
    def setup_context(ctx, inputs, output):
        x, b, a = inputs
        ctx.save_for_backward(x, b, a, output)
        ctx.save_for_forward(x, b, a, output)

    @staticmethod
    def backward(ctx, grad_y):
        x, b, a, y = ctx.saved_tensors
        b_np, a_np = _numpy(b), _numpy(a)
        unit_b = np.ones((b_np.shape[0], 1))
        g_tilde = _lfilter(unit_b, a_np, _numpy(grad_y)[:, ::-1].copy())[:, ::-1]
        grad_x = grad_b = grad_a = None
        if ctx.needs_input_grad[0]:
            gx = _lfilter(b_np, np.zeros((a_np.shape[0], 0)), g_tilde[:, ::-1].copy())[:, ::-1]
            grad_x = torch.from_numpy(gx.copy()).to(x)
        if ctx.needs_input_grad[1]:
            grad_b = torch.from_numpy(_lagged_products(g_tilde, _numpy(x), b_np.shape[1])).to(b)
        if ctx.needs_input_grad[2]:
            shifted = _lagged_products(g_tilde, _numpy(y), a_np.shape[1] + 1)[:, 1:]
            grad_a = torch.from_numpy(-shifted).to(a)
        return grad_x, grad_b, grad_a

    @staticmethod
    def jvp(ctx, dx, db, da):
        x, b, a, y = ctx.saved_tensors
        C = x.shape[-1]
        drive = torch.zeros_like(y)
        no_poles = torch.zeros(C, 0, dtype=x.dtype, device=x.device)
        if dx is not None:
            drive = drive + _IIRFilter.apply(dx, b, no_poles)
        if db is not None:
            drive = drive + _IIRFilter.apply(x, db, no_poles)
        if da is not None:
            da_full = torch.cat([torch.zeros(C, 1, dtype=da.dtype, device=da.device), da], dim=1)
            drive = drive - _IIRFilter.apply(y, da_full, no_poles)
        ones = torch.ones(C, 1, dtype=x.dtype, device=x.device)
        return _IIRFilter.apply(drive, ones, a)


def iir_filter(x: torch.Tensor, b: torch.Tensor, a: torch.Tensor) -> torch.Tensor:
    r"""Filter each channel of ``x`` by $B_c(q)/A_c(q)$ from rest.

    Args:
        x: input, shape (batch, time, channel).
        b: numerators, shape (channel, n_b): $b_{c,0} + b_{c,1} q^{-1} + \dots$.
        a: denominators without the leading 1, shape (channel, n_a): $1 + a_{c,1} q^{-1} + \dots$.

    Returns:
        y: shape (batch, time, channel), differentiable in ``x``, ``b`` and ``a`` (reverse and
        forward mode).
    """
    if x.dim() != 3:
        raise ConfigurationError(f"iir_filter expects x of shape (batch, time, channel), got {tuple(x.shape)}")
    C = x.shape[-1]
    if b.dim() != 2 or b.shape[0] != C or a.dim() != 2 or a.shape[0] != C:
        raise ConfigurationError(
            f"iir_filter expects b (channel, n_b) and a (channel, n_a) with channel={C}, "
            f"got b {tuple(b.shape)} and a {tuple(a.shape)}"
        )
    return _IIRFilter.apply(x, b, a)
