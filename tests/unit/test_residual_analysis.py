"""``residual_analysis``: the resid-style correlations and bounds against signals of known structure."""

import numpy as np
import pytest
from scipy import signal as sps

from torchpaml import residual_analysis, residual_analysis_figure

N = 5000


@pytest.fixture
def rng():
    return np.random.default_rng(0)


def test_white_residual_independent_of_the_input_stays_inside_the_bounds(rng):
    u, e = rng.standard_normal(N), rng.standard_normal(N)
    result = residual_analysis(u, e)
    assert result.autocorrelation[0] == pytest.approx(1.0)
    assert result.autocorrelation_bound == pytest.approx(2.5758 / np.sqrt(N), rel=1e-4)  # z_0.995 / sqrt(N)
    # 25 + 51 lags at a 1 % false-alarm rate each: a couple outside is chance, not structure
    assert len(result.autocorrelation_outside) <= 2 and len(result.cross_correlation_outside) <= 2


def test_coloured_residual_fails_whiteness(rng):
    e = sps.lfilter([1.0], [1.0, -0.8], rng.standard_normal(N))  # AR(1): rho(1) = 0.8
    result = residual_analysis(rng.standard_normal(N), e)
    assert result.autocorrelation[1] == pytest.approx(0.8, abs=0.03)  # sampling error ~ 1/sqrt(N)
    assert list(result.autocorrelation_outside[:5]) == [1, 2, 3, 4, 5]


def test_residual_that_follows_the_input_fails_independence_at_the_right_lag(rng):
    u = rng.standard_normal(N)
    e = 0.5 * np.roll(u, 3) + rng.standard_normal(N)  # e(t) depends on u(t - 3)
    result = residual_analysis(u, e)
    peak = result.cross_lags[np.argmax(np.abs(result.cross_correlation))]
    assert peak == 3 and 3 in result.cross_correlation_outside
    assert len(residual_analysis_figure(result).axes) == 2


def test_the_record_must_be_longer_than_the_lags():
    with pytest.raises(ValueError, match="above 2\\*lags"):
        residual_analysis(np.ones(40), np.ones(40))
