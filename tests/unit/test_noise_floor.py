"""The noise floor read from records by differences, against the noise added to simulated records.

Oracle: the white output noise that ``Simulated`` adds, as a fraction of each record's RMS. Tolerance: within 2 %
of it (relative) on records sampled several times faster than they move, where the estimate is tight; it is an upper
bound (never below the noise by more than its own spread, 2 % at 4 000 samples) and 0.1 % of the RMS at most on a
noise-free record. The Duffing is damped (zeta = 0.3): at zeta = 0.1 its multisine response is chaotic, so its
records, and whether their period differences pass as noise, change with the simulation's rounding.
"""

import pytest
import torch

from torchpaml import CoulombFriction, CubicStiffness, Oscillator, Pendulum, Record, Simulated
from torchpaml._diagnostics.analysis.noise_floor import MIN_RUN_SAMPLES, input_period, noise_floor
from torchpaml.leaderboard import noise_floor as leaderboard_noise_floor
from tests.two_mass import TwoMass

SYSTEMS = {
    "oscillator with friction": lambda: Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CoulombFriction(
        0.5, eps=0.05),
    "pendulum": lambda: Pendulum(learn=()),
    "duffing": lambda: Oscillator(zeta=0.3, omega0=1.0, learn=()) + CubicStiffness(1.0),  # damped: not chaotic
}


def _records(system, signal: str, dt: float, noise: float, seeds=(1,)) -> list[Record]:
    return Simulated(system(), signal, seeds=list(seeds), amplitude=1.0, duration=4000 * dt, dt=dt,
                     noise=noise).experiments()


@pytest.mark.parametrize("dt", [0.05, 0.1])
@pytest.mark.parametrize("signal", ["pseudorandom", "multisine"])
@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_the_floor_is_the_noise_added(name, signal, dt):
    for noise in (0.005, 0.01, 0.02):
        assert noise_floor(_records(SYSTEMS[name], signal, dt, noise)) == pytest.approx(noise, rel=0.02)
    assert noise_floor(_records(SYSTEMS[name], signal, dt, 0.0)) < 0.001


def test_records_and_channels_are_pooled():
    two = _records(SYSTEMS["pendulum"], "pseudorandom", 0.05, 0.01, seeds=(1, 2))  # noise relative to each
    assert noise_floor(two) == pytest.approx(0.01, rel=0.02)
    chain = Simulated(TwoMass(), "multisine", seeds=[1], amplitude=1.0, duration=200.0, dt=0.05,
                      noise=0.01).experiments()
    assert chain[0].y.shape[1] == 2 and noise_floor(chain) == pytest.approx(0.01, rel=0.03)


def test_an_output_that_moves_between_samples_reads_an_upper_bound():
    """White noise alone (nothing smooth to separate) reads its own level; a sine near the Nyquist frequency plus
    1 % noise reads above 1 %."""
    generator = torch.Generator().manual_seed(0)
    t = torch.arange(4000, dtype=torch.float64)
    u = torch.zeros(4000, 1, dtype=torch.float64)
    white = torch.randn(4000, 1, generator=generator, dtype=torch.float64)
    assert noise_floor([Record(t, u, white)]) == pytest.approx(1.0, rel=0.03)
    fast = torch.sin(2.5 * t)[:, None] * 2 ** 0.5
    noisy = fast + 0.01 * torch.randn(4000, 1, generator=generator, dtype=torch.float64)
    assert noise_floor([Record(t, u, noisy)]) > 0.02


def test_where_the_input_repeats_the_floor_is_read_from_the_repeats():
    """An output that moves at every sample (white, repeated with its input every 500 samples, six times) plus 1 %
    noise: the differences read the signal (far above 1 %), the repeats read the noise within 3 % (its spread over
    2 000 differences); a response that does not repeat with its input is read by differences; scaled by another
    record's RMS."""
    generator = torch.Generator().manual_seed(2)
    period, samples = 500, 3000
    u = torch.randn(period, 1, generator=generator, dtype=torch.float64).repeat(samples // period, 1)
    t = torch.arange(samples, dtype=torch.float64)
    y = u + 0.01 * torch.randn(samples, 1, generator=generator, dtype=torch.float64)
    record = Record(t, u, y)
    assert input_period(record) == period
    assert noise_floor([record]) == pytest.approx(0.01, rel=0.03)
    drifting = Record(t, u, y + torch.linspace(0, 3, samples, dtype=torch.float64)[:, None])
    assert noise_floor([drifting]) > 0.1  # its period differences are the drift, not noise: by differences
    other = Record(t, torch.randn(samples, 1, generator=generator, dtype=torch.float64), y)
    assert input_period(other) is None and noise_floor([other]) > 0.5
    assert noise_floor([record], [Record(t[:1000], u[:1000], 2 * y[:1000])]) == pytest.approx(0.005, rel=0.03)


def test_where_the_input_repeats_only_in_runs_the_floor_is_read_from_them():
    """Eight realisations of a white input, each preceded by its own last 300 samples (as Silverbox's multisines
    are), through a response with memory (y_k = u_k + 0.8 y_{k-1}) plus 1 % noise: the input never repeats as a whole,
    the differences read the signal, and the runs of repeats read the noise within 10 % (about 1 200 settled
    samples). The leaderboard's reading at the known lag is the same number."""
    generator = torch.Generator().manual_seed(3)
    period, lead = 1000, 300
    blocks = [torch.randn(period, generator=generator, dtype=torch.float64) for _ in range(8)]
    u = torch.cat([torch.cat([block[-lead:], block]) for block in blocks])[:, None]
    response = torch.zeros_like(u)
    for k in range(len(u)):
        response[k] = u[k] + (0.8 * response[k - 1] if k else 0.0)
    noise = 0.01 * float(response.square().mean().sqrt())
    y = response + noise * torch.randn(response.shape, generator=generator, dtype=torch.float64)
    record = Record(torch.arange(len(u), dtype=torch.float64), u, y)
    assert input_period(record) is None
    rms = float(y.square().mean().sqrt())
    floor = noise_floor([record])
    assert floor == pytest.approx(0.01 * float(response.square().mean().sqrt()) / rms, rel=0.1)
    reading, samples = leaderboard_noise_floor(record, period)
    assert samples >= MIN_RUN_SAMPLES and floor * rms == pytest.approx(reading, rel=1e-12)
    assert noise_floor([Record(record.t, torch.randn(u.shape, generator=generator, dtype=torch.float64), y)]) > 0.1
