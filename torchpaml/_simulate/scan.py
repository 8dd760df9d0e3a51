r"""The linear recurrence $z_{s+1} = A_s z_s + b_s$ solved by odd-even reduction (a parallel scan).

Each step is the affine map $M_s(z) = A_s z + b_s$. Composing the steps in pairs,
$M_{2i+1} \circ M_{2i} = (A_{2i+1} A_{2i},\ A_{2i+1} b_{2i} + b_{2i+1})$, gives a recurrence of half the
length for the even states $z_0, z_2, \dots$, solved the same way; then every odd state is one step
from the even state before it, $z_{2i+1} = A_{2i} z_{2i} + b_{2i}$. Each of the $\lceil\log_2 K\rceil$
levels is a handful of batched matrix products on half the previous length, so the arithmetic is
$O(K)$ in all and only $O(\log K)$ operations are dispatched; autograd differentiates it like any
other torch code.

With one matrix for every step (:func:`constant_recurrence`, a linear time-invariant system) the pairs share
$A^2$, the next level $A^4$, and so on: one $n \times n$ matrix per level, never one per step. That recurrence
is stepped sequentially in C where the machine compiles
(:mod:`~torchpaml._simulate.compiled_recurrence`, about ten times faster on one core); the scan is its fallback.
"""

from __future__ import annotations

import torch

from torchpaml._simulate.compiled_recurrence import sequential_recurrence

__all__ = ["constant_recurrence", "linear_recurrence"]


def linear_recurrence(A: torch.Tensor, b: torch.Tensor, z0: torch.Tensor) -> torch.Tensor:
    r"""$z_0$ and $z_{s+1} = A_s z_s + b_s$ for $s = 0 \dots K-1$.

    Args:
        A: (batch, K, n, n).
        b: (batch, K, n).
        z0: (batch, n).

    Returns:
        z: (batch, K + 1, n), with ``z[:, 0] = z0``.
    """
    K = A.shape[1]
    if K <= 1:
        return torch.cat([z0[:, None], (A @ z0[:, None, :, None])[..., 0] + b], dim=1)
    pairs = K // 2 * 2
    first, second = A[:, 0:pairs:2], A[:, 1:pairs:2]
    even = linear_recurrence(second @ first, (second @ b[:, 0:pairs:2, :, None])[..., 0] + b[:, 1:pairs:2], z0)
    odd = (first @ even[:, :-1, :, None])[..., 0] + b[:, 0:pairs:2]  # z_1, z_3, ..., z_{pairs-1}
    z = torch.stack([even[:, :-1], odd], dim=2).flatten(1, 2)  # z_0 ... z_{pairs-1}
    if K > pairs:  # K odd: the last step from z_{pairs}
        last = (A[:, -1] @ even[:, -1, :, None])[..., 0] + b[:, -1]
        return torch.cat([z, even[:, -1:], last[:, None]], dim=1)
    return torch.cat([z, even[:, -1:]], dim=1)


def constant_recurrence(A: torch.Tensor, b: torch.Tensor, z0: torch.Tensor) -> torch.Tensor:
    r"""$z_0$ and $z_{s+1} = A z_s + b_s$ for $s = 0 \dots K-1$, one matrix for every step: the sequential loop in C
    (:mod:`~torchpaml._simulate.compiled_recurrence`), else the scan (module docstring).

    Both step the states themselves: on poles within $10^{-3}$ of $z = 1$ the scan agrees with the sequential
    recursion to about $10^{-13}$, where a transfer function's direct form, whose $n$-fold cluster of roots
    amplifies every rounding by about $\delta^{-n}$, loses most of its digits.

    Derivatives by the adjoint recursion, itself one recurrence: with $\lambda_K = g_K$ and
    $\lambda_s = g_s + A^\top \lambda_{s+1}$ for the cotangents $g_s$ of $z_s$, the gradients are
    $\partial L/\partial b_s = \lambda_{s+1}$, $\partial L/\partial z_0 = \lambda_0$ and
    $\partial L/\partial A = \sum_s \lambda_{s+1} z_s^\top$; forward mode is the recurrence of
    $\dot z_{s+1} = A \dot z_s + \dot A z_s + \dot b_s$. Both cost one recurrence, where reverse mode through the
    scan's levels costs several.

    Args:
        A: (n, n).
        b: (batch, K, n).
        z0: (batch, n).

    Returns:
        z: (batch, K + 1, n), with ``z[:, 0] = z0``.
    """
    return _ConstantRecurrence.apply(A, b, z0)


class _ConstantRecurrence(torch.autograd.Function):
    """:func:`constant_recurrence` with its adjoint (reverse mode) and tangent (forward mode) recurrences."""

    @staticmethod
    def forward(A, b, z0):
        return _stepped(A, b, z0)

    @staticmethod
    def setup_context(ctx, inputs, output):
        ctx.save_for_backward(inputs[0], output)
        ctx.save_for_forward(inputs[0], output)

    @staticmethod
    def backward(ctx, grad):
        A, z = ctx.saved_tensors
        # the recurrence itself: where the backward is differentiated (create_graph), it records its own node
        adjoint = constant_recurrence(A.T, grad.flip(1)[:, 1:], grad[:, -1]).flip(1)  # lambda_0 .. lambda_K
        return torch.einsum("bsi,bsj->ij", adjoint[:, 1:], z[:, :-1]), adjoint[:, 1:], adjoint[:, 0]

    @staticmethod
    def jvp(ctx, dA, db, dz0):
        A, z = ctx.saved_tensors
        drive = torch.zeros_like(z[:, 1:]) if db is None else db
        if dA is not None:
            drive = drive + z[:, :-1] @ dA.T
        return _stepped(A, drive, torch.zeros_like(z[:, 0]) if dz0 is None else dz0)


def _stepped(A: torch.Tensor, b: torch.Tensor, z0: torch.Tensor) -> torch.Tensor:
    """:func:`constant_recurrence` without its derivatives: C's sequential loop
    (:func:`~torchpaml._simulate.compiled_recurrence.sequential_recurrence`), else the odd-even reduction."""
    z = sequential_recurrence(A, b, z0)
    return _halving(A, b, z0) if z is None else z


def _halving(A: torch.Tensor, b: torch.Tensor, z0: torch.Tensor) -> torch.Tensor:
    """The odd-even reduction of :func:`constant_recurrence`, in plain torch operations."""
    K = b.shape[1]
    if K <= 1:
        return torch.cat([z0[:, None], z0[:, None] @ A.T + b], dim=1)
    pairs = K // 2 * 2
    even = _halving(A @ A, b[:, 0:pairs:2] @ A.T + b[:, 1:pairs:2], z0)  # z_0, z_2, ..., z_pairs
    odd = even[:, :-1] @ A.T + b[:, 0:pairs:2]  # z_1, z_3, ..., z_{pairs-1}
    z = torch.stack([even[:, :-1], odd], dim=2).flatten(1, 2)
    if K > pairs:
        return torch.cat([z, even[:, -1:], even[:, -1:] @ A.T + b[:, -1:]], dim=1)
    return torch.cat([z, even[:, -1:]], dim=1)
