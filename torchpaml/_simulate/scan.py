r"""The linear recurrence $z_{s+1} = A_s z_s + b_s$ solved by odd-even reduction (a parallel scan).

Each step is the affine map $M_s(z) = A_s z + b_s$. Composing the steps in pairs,
$M_{2i+1} \circ M_{2i} = (A_{2i+1} A_{2i},\ A_{2i+1} b_{2i} + b_{2i+1})$, gives a recurrence of half the
length for the even states $z_0, z_2, \dots$, solved the same way; then every odd state is one step
from the even state before it, $z_{2i+1} = A_{2i} z_{2i} + b_{2i}$. Each of the $\lceil\log_2 K\rceil$
levels is a handful of batched matrix products on half the previous length, so the arithmetic is
$O(K)$ in all and only $O(\log K)$ operations are dispatched; autograd differentiates it like any
other torch code.
"""

from __future__ import annotations

import torch

__all__ = ["linear_recurrence"]


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
