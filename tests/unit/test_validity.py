"""Where the physics holds: binned errors and the validity map, on the paper's pendulum."""

import numpy as np
import pytest
import torch

from torchpaml import Oscillator, Pendulum, Simulated
from torchpaml.analysis import error_by_amplitude, validity_map
from torchpaml.figures import validity_figure


def test_binned_mismatch_matches_a_direct_computation():
    u = torch.linspace(-2, 2, 401, dtype=torch.float64)
    y, y_model = u**3, u**3 + 0.1 * u
    bins = error_by_amplitude(u, y, y_model, bins=4)
    assert bins.counts.sum() == 401 and np.allclose(bins.edges, [0, 0.5, 1.0, 1.5, 2.0])
    top = u.abs() >= 1.5
    assert bins.mismatch[-1] == pytest.approx(float((0.1 * u[top]).norm() / y[top].norm()), rel=1e-12)
    assert bins.mismatch[0] > bins.mismatch[-1]  # a relative error of 0.1/u^2 shrinks with |u|


def test_the_linearised_pendulum_holds_for_small_swings_and_breaks_for_large_ones():
    truth = Pendulum(zeta=0.5, omega0=2.0, learn=())

    def measure(amplitude, omega):
        return Simulated(truth, "sine", amplitude, duration=30.0, omega=omega).experiments()[0]

    result = validity_map(Oscillator(zeta=0.5, omega0=2.0), measure, [0.5, 4.0, 10.0], [0.5, 2.0])
    small, large = result.mismatch[0], result.mismatch[-1]
    assert np.all(small < 0.02) and np.all(large > 0.3)  # sin x ≈ x to 1 % below |x| ≈ 0.25 rad
    assert np.all(np.diff(result.mismatch, axis=0) > 0)  # worse with every step up in amplitude
    assert len(validity_figure(result).axes) == 2  # the map and its colour bar
