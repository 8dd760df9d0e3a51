"""The linear recurrences against the sequential loop in torch: the parallel scans, and the constant recurrence's
compiled loop (each constant-recurrence test runs on both paths: ``path``).

Tolerance: the odd-even reduction multiplies the same matrices in another order, so it agrees with
the loop to rounding, 1e-12 relative for contracting maps (spectral radius below 1) over 1000 steps,
and for a lightly damped fifth-order system sampled 1000 times faster than its poles over 20 000 steps.
"""

import numpy as np
import pytest
import torch

from torchpaml._simulate import scan
from torchpaml._simulate.compiled_recurrence import sequential_recurrence
from torchpaml._simulate.lti import discrete_states, discretize
from torchpaml._simulate.scan import constant_recurrence, linear_recurrence


@pytest.fixture(params=["compiled", "scan"])
def path(request, monkeypatch):
    """The constant recurrence's path: C's sequential loop (the default), or the scan it falls back to."""
    if request.param == "scan":
        monkeypatch.setattr(scan, "sequential_recurrence", lambda A, b, z0: None)
    else:
        assert sequential_recurrence(*(torch.zeros(s, dtype=torch.float64) for s in ((1, 1), (1, 1, 1), (1, 1)))) \
            is not None, "this machine has no C compiler: the compiled path is not tested"
    return request.param


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


@pytest.mark.parametrize("K", [0, 1, 2, 3, 5, 8, 13, 64, 1000])
def test_the_constant_recurrence_equals_the_sequential_loop(K, path):
    _, b, z0 = _problem(K)
    A = torch.tensor([[0.6, 0.5], [-0.4, 0.7]], dtype=torch.float64)  # poles 0.65 +- 0.44j
    expected = _sequential(A.expand(3, K, 2, 2), b, z0)
    z = constant_recurrence(A, b, z0)
    assert z.shape == (3, K + 1, 2)
    assert torch.allclose(z, expected, rtol=1e-12, atol=1e-12 * float(expected.abs().max()))


def test_the_constant_recurrence_is_exact_with_every_pole_near_one(path):
    """The Chebyshev residual's default filter (poles -1.5 +- 1j, -1.5 +- 6j, -1.5 1/s) sampled at h = 1 ms: every
    pole within 0.006 of z = 1. The states agree with the sequential loop to 1e-12 of each state's norm, and an input
    perturbed by 1e-12 moves them by no more than 1e-10 (a direct-form transfer function moved them by 2e-3)."""
    poles = [complex(-1.5, 1.0), complex(-1.5, -1.0), complex(-1.5, 6.0), complex(-1.5, -6.0), -1.5]
    denominator = torch.tensor(np.real(np.poly(poles)), dtype=torch.float64)
    A = torch.cat([torch.eye(5, dtype=torch.float64)[1:], -denominator.flip(0)[:5][None]])
    B = torch.zeros(5, 1, dtype=torch.float64)
    B[-1, 0] = 1.0
    Phi, G0, G1 = discretize(A, B, 1e-3)
    g = torch.Generator().manual_seed(2)
    u = torch.rand(2, 20000, 1, generator=g, dtype=torch.float64).cumsum(1).sin()
    drive = u[:, :-1] @ G0.T + u[:, 1:] @ G1.T
    x0 = torch.zeros(2, 5, dtype=torch.float64)
    z = constant_recurrence(Phi, drive, x0)
    expected = _sequential(Phi.expand(2, 19999, 5, 5), drive, x0)
    assert float(((z - expected).norm(dim=1) / expected.norm(dim=1)).max()) < 1e-12
    signs = torch.randint(0, 2, u.shape, generator=g).to(torch.float64) * 2 - 1
    nudged = u * (1 + 1e-12 * signs)
    moved = constant_recurrence(Phi, nudged[:, :-1] @ G0.T + nudged[:, 1:] @ G1.T, x0)
    assert float(((moved - z).norm(dim=1) / z.norm(dim=1)).max()) < 1e-10


def test_the_constant_recurrences_adjoint_and_tangent_match_finite_differences(path):
    """Reverse mode (the adjoint scan), forward mode (the tangent scan) and the second derivatives through the
    adjoint, against central differences."""
    A, b, z0 = _problem(11, n=3, batch=2, seed=1)
    inputs = (A[0, 0].clone().requires_grad_(), b.requires_grad_(), z0.requires_grad_())
    assert torch.autograd.gradcheck(constant_recurrence, inputs, check_forward_ad=True)
    assert torch.autograd.gradgradcheck(constant_recurrence, inputs)


@pytest.mark.parametrize("inputs", [1, 2])
def test_the_forced_loop_is_the_recurrence_on_its_drives(inputs):
    """``discrete_states`` without a derivative recorded forms each drive inside C's loop; with one input its states
    are those of the recurrence on the drives ``u @ G0.T + u @ G1.T`` to the last bit, with two within 1e-14 (the
    products' sums in another order); with a derivative recorded it takes the drives and the recurrence."""
    poles = torch.tensor([[0.0, 1.0], [-4.0, -0.8]], dtype=torch.float64)
    g = torch.Generator().manual_seed(5)
    B = torch.randn(2, inputs, generator=g, dtype=torch.float64)
    Phi, G0, G1 = discretize(poles, B, 0.05)
    u = torch.randn(3, 4000, inputs, generator=g, dtype=torch.float64)
    x0 = torch.randn(3, 2, generator=g, dtype=torch.float64)
    with torch.no_grad():
        forced = discrete_states(Phi, G0, G1, u, x0)
        on_drives = constant_recurrence(Phi, (u @ G0.T)[:, :-1] + (u @ G1.T)[:, 1:], x0)
    recorded = discrete_states(Phi.clone().requires_grad_(), G0, G1, u, x0)
    assert recorded.requires_grad and torch.equal(recorded.detach(), on_drives)
    if inputs == 1:
        assert torch.equal(forced, on_drives)
    else:
        assert float((forced - on_drives).abs().max()) <= 1e-14 * float(on_drives.abs().max())
