"""The parallel scan of the linear recurrence against the sequential loop it replaces.

Tolerance: the odd-even reduction multiplies the same matrices in another order, so it agrees with
the loop to rounding, 1e-12 relative for contracting maps (spectral radius below 1) over 1000 steps.
"""

import pytest
import torch

from torchpaml._simulate.scan import linear_recurrence


def _sequential(A, b, z0):
    z = [z0]
    for s in range(A.shape[1]):
        z.append((A[:, s] @ z[-1][..., None])[..., 0] + b[:, s])
    return torch.stack(z, dim=1)


def _problem(K, n=2, batch=3, seed=0):
    g = torch.Generator().manual_seed(seed)
    A = 0.45 * torch.randn(batch, K, n, n, generator=g, dtype=torch.float64)
    return A, torch.randn(batch, K, n, generator=g, dtype=torch.float64), torch.randn(batch, n, generator=g,
                                                                                       dtype=torch.float64)


@pytest.mark.parametrize("K", [0, 1, 2, 3, 5, 8, 13, 64, 1000])
def test_scan_equals_the_sequential_recurrence(K):
    A, b, z0 = _problem(K)
    expected = _sequential(A, b, z0)
    z = linear_recurrence(A, b, z0)
    assert z.shape == (3, K + 1, 2)
    assert torch.allclose(z, expected, rtol=1e-12, atol=1e-12 * float(expected.abs().max()))


def test_scan_gradients_match_finite_differences():
    A, b, z0 = (a.requires_grad_() for a in _problem(11, n=3, batch=2, seed=1))
    assert torch.autograd.gradcheck(linear_recurrence, (A, b, z0))
