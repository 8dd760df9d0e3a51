r"""The linear recurrence $z_{s+1} = A_s z_s + b_s$ solved by a parallel (doubling) scan.

Each step is the affine map $M_s(z) = A_s z + b_s$. The prefix compositions
$P_s = M_s \circ \dots \circ M_0$ are formed in $\lceil\log_2 K\rceil$ rounds (Hillis-Steele): in the
round with offset $o$, every prefix ending at $s \ge o$ is composed with the one ending at $s - o$,
$(A, b)_s \leftarrow (A_s A_{s-o},\ A_s b_{s-o} + b_s)$. Every round is a handful of batched matrix
products, so the cost is $O(K\log K)$ arithmetic but only $O(\log K)$ dispatched operations, and
autograd differentiates it like any other torch code.
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
    offset = 1
    while offset < K:
        A_late, b_late = A[:, offset:], b[:, offset:]
        composed_A = A_late @ A[:, :-offset]
        composed_b = (A_late @ b[:, :-offset, :, None])[..., 0] + b_late
        A = torch.cat([A[:, :offset], composed_A], dim=1)
        b = torch.cat([b[:, :offset], composed_b], dim=1)
        offset *= 2
    later = (A @ z0[:, None, :, None])[..., 0] + b
    return torch.cat([z0[:, None], later], dim=1)
