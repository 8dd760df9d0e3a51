"""``residual_analysis``: the resid-style correlations and bounds against signals of known structure."""

import numpy as np
import pytest
from scipy import signal as sps

from torchpaml.analysis import residual_analysis
from torchpaml.figures import residual_analysis_figure

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


def test_the_linear_share_is_the_variance_a_filter_of_the_input_explains(rng):
    """A residual = an FIR filter of a white input (variance 1.25) + independent noise (variance 1): the Wiener
    filter explains 1.25 / 2.25 of it; independent of the input, only the chance fit of 26 taps to N samples,
    about 26 / N. Sampling error ~ 1/sqrt(N) = 0.014."""
    u = rng.standard_normal(N)
    filtered = sps.lfilter([1.0, 0.5], [1.0], u)  # variance 1 + 0.25
    assert residual_analysis(u, filtered + rng.standard_normal(N)).linear_share == pytest.approx(1.25 / 2.25,
                                                                                                 abs=0.03)
    # exact but for the biased (1/N) correlation estimates' end effects, O(taps/N) = 0.005
    assert residual_analysis(u, filtered).linear_share == pytest.approx(1.0, abs=5e-3)
    assert residual_analysis(u, rng.standard_normal(N)).linear_share < 0.02
    assert residual_analysis(np.zeros(N), rng.standard_normal(N)).linear_share == 0.0
