"""Certificates: the Chebyshev residual is orthogonal to the physics and its sensitivity; the MLP is not."""

from torchpaml import Oscillator
from torchpaml.analysis import incompatibility_certificates
from torchpaml._certificates import draw_chebyshev, draw_mlp


def _worst(draw, duration):
    physics = Oscillator(zeta=0.6348)
    return incompatibility_certificates(
        physics, draw, alpha=4.0, parameter="zeta", duration=duration, draws=5, samples_per_period=200
    ).worst


def test_chebyshev_certificates_below_1e3_and_shrinking_with_T():
    cheb = lambda g: draw_chebyshev(4.0, g)  # noqa: E731
    short, long = _worst(cheb, 20.0), _worst(cheb, 80.0)
    assert max(long) < 1e-3
    assert long[0] < short[0] and long[1] < short[1]


def test_mlp_certificates_are_far_from_zero():
    zeroth, first = _worst(lambda g: draw_mlp(4.0, g), 80.0)
    assert zeroth > 0.1 and first > 0.1
