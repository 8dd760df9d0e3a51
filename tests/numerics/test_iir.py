"""The IIR primitive against scipy, and its reverse- and forward-mode derivatives (gradcheck, float64)."""

import numpy as np
import torch
from scipy import signal

from torchpaml.engine import iir_filter


def _inputs(seed=0, channels=3, time=40):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(2, time, channels, generator=g, requires_grad=True)
    b = torch.randn(channels, 3, generator=g, requires_grad=True)
    a = (0.3 * torch.randn(channels, 2, generator=g)).requires_grad_()  # stable: |roots| < 1
    return x, b, a


def test_matches_scipy_lfilter_per_channel():
    x, b, a = _inputs()
    y = iir_filter(x, b, a).detach().numpy()
    for c in range(3):
        ref = signal.lfilter(b[c].detach().numpy(), np.r_[1.0, a[c].detach().numpy()], x[..., c].detach().numpy())
        np.testing.assert_allclose(y[..., c], ref, rtol=1e-12, atol=1e-14)


def test_reverse_mode_gradcheck():
    assert torch.autograd.gradcheck(iir_filter, _inputs())


def test_forward_mode_gradcheck():
    assert torch.autograd.gradcheck(
        iir_filter, _inputs(1), check_forward_ad=True, check_backward_ad=False, check_undefined_grad=False
    )


def test_shape_errors_name_the_expected_shapes():
    x, b, a = _inputs()
    import pytest

    with pytest.raises(ValueError, match=r"\(batch, time, channel\)"):
        iir_filter(x[0], b, a)
    with pytest.raises(ValueError, match="channel=3"):
        iir_filter(x, b[:2], a)
