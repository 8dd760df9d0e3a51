"""``harmonic_fingerprint`` against residuals of known harmonic content."""

import math

import numpy as np
import pytest

from torchpaml.analysis import harmonic_fingerprint

T = np.arange(0, 40 * math.pi, 0.01)  # 20 periods of 1 rad/s


def test_energy_lands_in_the_right_bins():
    u = 2.0 * np.cos(T)
    e = 0.3 * np.cos(3 * T) + 0.2 * np.sin(2 * T) + 0.1 + 0.05 * np.cos(T)
    result = harmonic_fingerprint(T, u, e, fundamental=1.0)
    assert result.excited == [1]
    expected = {"odd": 0.3**2 / 2, "even": 0.2**2 / 2, "dc": 0.1**2, "excited": 0.05**2 / 2}
    total = sum(expected.values())  # the components are orthogonal over whole periods
    for name, value in expected.items():
        assert result.shares[name] == pytest.approx(value / total, rel=1e-3)  # periods end off-grid: ~1e-4 leakage
    assert result.shares["other"] < 1e-6


def test_noise_goes_to_other_and_shares_sum_to_one():
    rng = np.random.default_rng(1)
    result = harmonic_fingerprint(T, np.cos(T), rng.standard_normal(len(T)), fundamental=1.0)
    assert result.shares["other"] > 0.99  # 31 fitted columns of 12 567 samples
    # the groups are orthogonal over whole periods only; this record ends off the grid (leakage ~1e-7)
    assert sum(result.shares.values()) == pytest.approx(1.0, rel=1e-5)


def test_the_window_must_resolve_the_harmonics():
    with pytest.raises(ValueError, match="above the Nyquist"):
        harmonic_fingerprint(T, np.cos(T), np.cos(T), fundamental=30.0)
    with pytest.raises(ValueError, match="less than one period"):
        harmonic_fingerprint(T[:100], np.cos(T[:100]), np.cos(T[:100]), fundamental=1.0)


def test_the_papers_linearised_pendulum_leaves_odd_harmonics():
    import torch

    from torchpaml import Record, Oscillator, fit_physics
    from torchpaml._paper import PaperSetup, _measure
    from torchpaml._signals import sine, time_grid

    t = time_grid(80.0, 0.01)
    u = sine(t, 4.0, 1.0)
    y = _measure(PaperSetup(), t, u)
    physics = Oscillator(zeta=1.0)
    fit_physics(physics, Record.records(t, u, y), bounds={"zeta": (1e-3, 5.0)})
    with torch.no_grad():
        result = harmonic_fingerprint(t, u, y - physics(t, u), fundamental=1.0, transient=20.0)
    # sin x is odd: the missing physics sits on 3ω, 5ω, ... (measured 0.73; the rest is on ω itself)
    assert result.shares["odd"] > 0.6 and result.shares["even"] < 1e-4 and result.shares["dc"] < 1e-4
