r"""The noise floor read from the records: the mismatch a model would have if its only error were the output noise.

**From repeats.** Where a record's input repeats at least three times (:func:`input_period`: its normalised
autocorrelation reaches :data:`REPEATS` at a lag $P$ of at least :data:`MIN_PERIOD` samples), the differences of
consecutive periods' outputs after the first, $d_j = y_{j+1} - y_j$ (each a period long), are differences of two
noise samples once the response repeats: $\hat\sigma^2 = \overline{d^2}/2$, whatever the signal's bandwidth and the
noise's colour. They are taken only where they are noise: then successive ones share one period's noise with
opposite signs, and their correlation is $-1/2$ (within four of its standard errors, $0.75/\sqrt n$ for $n$
products, and at most :data:`NOISE_CORRELATION`), and the differences
two periods apart have the same mean square as one apart (:data:`SPREAD`: within 25 %); a response that still
settles, that repeats only every second period, or that does not repeat at all (a chaotic one) fails one or the
other.

**From repeated runs.** Where the input repeats only in parts (each realisation of a multisine preceded by its own
last samples, as Silverbox's records are), the runs where $u_k \approx u_{k+P}$ (:func:`repeated_runs`: over
:data:`RUN_WINDOW` samples, the mean gap below :data:`RUN_GAP` of the input's RMS) give $y_k - y_{k+P}$ over each
run's second half, once the response has settled: the difference of two noise samples, $\hat\sigma^2 =
\overline{d^2}/2$. The lag is searched among the :data:`LAGS` lags whose input autocorrelation is the most
significant ($r_P\sqrt{n - P}$ largest), and the one with the most settled samples (at least
:data:`MIN_RUN_SAMPLES`) is read. Where the response has not settled the difference holds signal too, so this
reading is an upper bound as well: the floor is the lower of it and the one by differences.

**By differences**, otherwise. The $k$-th difference of white noise has variance $\binom{2k}{k}\sigma^2$, while a
signal sampled faster than it changes has $k$-th differences that shrink like $(\omega h)^k$:

$$ \hat\sigma^2 = \min_{1 \le k \le K} \frac{\sum (\Delta^k y)^2}{(N - k)\binom{2k}{k}} $$

($K$ = :data:`MAX_ORDER`). For white noise the signal only adds, so this is an upper bound: tight where the output
is sampled several times faster than it moves (within 2 % of the noise added to simulated pendulum, oscillator and
Duffing records at 10 and 20 samples per second, ``tests/unit/test_noise_floor.py``), loose where the record's
bandwidth nears the Nyquist frequency (Silverbox's records read 1.9 % by differences, 0.54 % from their repeated
runs).
Noise that is not white reads low, as the differences shrink it with the signal: Bouc-Wen's training record reads
0.87 % by differences and 1.12 % from its repeats (its benchmark states 1.2 %).

The floor is $\sqrt{\tfrac1C \sum_c \hat\sigma_c^2 / \overline{y_c^2}}$ over the output channels, in the units of
:func:`~torchpaml.mismatch` (a fraction of the RMS of the records it is compared with).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from torchpaml._data import Record

__all__ = ["LAGS", "MAX_ORDER", "MIN_PERIOD", "MIN_RUN_SAMPLES", "NOISE_CORRELATION", "REPEATS", "RUN_GAP", "RUN_WINDOW",
           "SPREAD", "input_period", "noise_floor", "repeated_runs", "settled_differences"]

#: The highest order of differences tried.
MAX_ORDER = 6
#: The shortest period of an input that repeats, in samples.
MIN_PERIOD = 64
#: The normalised autocorrelation of the input at a lag from which it repeats at that lag.
REPEATS = 0.999
#: The most the correlation of successive period differences may stray from -1/2 for them to be noise (less on
#: fewer samples: four standard errors).
NOISE_CORRELATION = 0.1
#: The most the log of the ratio of the two-period differences' mean square to the one-period differences' may stray
#: from 0 (noise: both are twice the noise variance; a settling response: about 4; a period-doubled one: about 0).
SPREAD = math.log(1.25)
#: The window, in samples, over which the input must repeat for a run of repeats (twice it: a run's shortest).
RUN_WINDOW = 64
#: The largest mean gap $|u_k - u_{k+P}|$ over a window, as a share of the input's RMS, within a run of repeats.
RUN_GAP = 0.1
#: How many of the most significant lags of the input's autocorrelation are searched for runs of repeats.
LAGS = 5
#: The fewest settled samples of runs of repeats that a reading rests on.
MIN_RUN_SAMPLES = 2 * RUN_WINDOW


def _autocorrelation(record: Record) -> torch.Tensor:
    r"""The normalised autocorrelation of ``record``'s input at every lag, (time,): $\sum u_k u_{k+P} / \sqrt{\sum
    u_k^2 \sum u_{k+P}^2}$ over the overlap, the input centred and its channels summed."""
    u = record.u.detach().to(torch.float64)
    u = u - u.mean(dim=0)
    n = u.shape[0]
    spectrum = torch.fft.rfft(u, 2 * n, dim=0)
    products = torch.fft.irfft(spectrum * spectrum.conj(), 2 * n, dim=0)[:n].sum(dim=1)
    energy = torch.cat([torch.zeros(1, dtype=u.dtype), torch.cumsum(u.square().sum(dim=1), 0)])
    lags = torch.arange(n)
    return products / torch.sqrt(energy[n - lags] * (energy[n] - energy[lags])).clamp(min=1e-300)


def input_period(record: Record) -> int | None:
    """The lag in samples at which ``record``'s input repeats at least three times: the largest normalised
    autocorrelation over the overlap for lags from :data:`MIN_PERIOD` to a third of the record, where it reaches
    :data:`REPEATS`; ``None`` where the input does not repeat so."""
    n = len(record.t)
    if n // 3 <= MIN_PERIOD:
        return None
    usable = _autocorrelation(record)[MIN_PERIOD:n // 3 + 1]
    best = int(torch.argmax(usable))
    return best + MIN_PERIOD if float(usable[best]) >= REPEATS else None


def repeated_runs(u: torch.Tensor, lag: int, window: int = RUN_WINDOW) -> list[torch.Tensor]:
    r"""The runs of samples $k$ where the input ``u`` (time, n_input) repeats ``lag`` samples on: the mean over
    ``window`` samples of $\|u_k - u_{k+P}\|$ below :data:`RUN_GAP` of the input's RMS, over more than ``2 *
    window`` consecutive samples; each run as its indices $k$ (ascending)."""
    u = u.detach().to(torch.float64)
    if lag >= u.shape[0] - 2 * window:
        return []
    gap = (u[:-lag] - u[lag:]).norm(dim=1)
    kernel = torch.ones(1, 1, window, dtype=gap.dtype) / window
    mean_gap = torch.nn.functional.conv1d(gap[None, None], kernel, padding=window // 2)[0, 0, :len(gap)]
    scale = float(u.square().sum(dim=1).mean().sqrt())
    repeats = torch.nonzero(mean_gap < RUN_GAP * scale).flatten()
    if len(repeats) == 0:
        return []
    breaks = torch.nonzero(torch.diff(repeats) > 1).flatten() + 1
    return [run for run in torch.tensor_split(repeats, breaks.tolist()) if len(run) > 2 * window]


def settled_differences(y: torch.Tensor, runs: list[torch.Tensor], lag: int) -> torch.Tensor:
    """$y_k - y_{k+P}$ over the second half of each run (the response settled), all runs concatenated; ``y``
    (time,)."""
    if not runs:
        return y.new_zeros(0)
    return torch.cat([y[run[len(run) // 2:]] - y[run[len(run) // 2:] + lag] for run in runs])


def _by_repeated_runs(records: Sequence[Record], channel: int) -> float | None:
    """The noise variance of one channel from the runs of repeats of the records' inputs (module docstring), pooled
    by samples; ``None`` where fewer than :data:`MIN_RUN_SAMPLES` settled samples repeat."""
    pieces = []
    for record in records:
        n = len(record.t)
        if n <= MIN_PERIOD + 2 * RUN_WINDOW:
            continue
        correlation = _autocorrelation(record)
        z = correlation * torch.sqrt((n - torch.arange(n)).to(torch.float64))  # its significance under whiteness
        usable = z[MIN_PERIOD:n - 2 * RUN_WINDOW]
        lags = (torch.topk(usable, min(LAGS, len(usable))).indices + MIN_PERIOD).tolist()
        y = record.y[:, channel].detach().to(torch.float64)
        found = [settled_differences(y, repeated_runs(record.u, lag), lag) for lag in lags]
        pieces.append(max(found, key=len))
    differences = torch.cat(pieces) if pieces else torch.zeros(0, dtype=torch.float64)
    return float(differences.square().mean()) / 2 if len(differences) >= MIN_RUN_SAMPLES else None


def _by_repeats(records: Sequence[Record], channel: int) -> float | None:
    """The noise variance of one channel from the records whose input repeats and whose period differences are noise
    (module docstring), pooled by samples; ``None`` where no record gives one."""
    squares, count = 0.0, 0
    for record in records:
        period = input_period(record)
        if period is None:
            continue
        y = record.y[:, channel].detach().to(torch.float64)
        periods = len(y) // period
        repeated = y[:periods * period].reshape(periods, period)
        differences = torch.diff(repeated, dim=0)[1:]  # after the first
        if differences.shape[0] < 2:
            continue
        first, second = differences[:-1].reshape(-1), differences[1:].reshape(-1)
        correlation = float((first * second).sum() / torch.sqrt(first.square().sum() * second.square().sum())
                            .clamp(min=1e-300))
        spread = float((repeated[3:] - repeated[1:-2]).square().mean() / differences.square().mean().clamp(min=1e-300))
        within = min(NOISE_CORRELATION, 3 / math.sqrt(first.numel()))  # four standard errors of the correlation
        if abs(correlation + 0.5) <= within and abs(math.log(spread)) <= SPREAD:
            squares += float(differences.square().sum()) / 2
            count += differences.numel()
    return squares / count if count else None


def _by_differences(outputs: list[torch.Tensor]) -> float:
    """The noise variance of one channel by differences (module docstring); 0 where no record is long enough."""
    variances = []
    for k in range(1, MAX_ORDER + 1):
        usable = [y for y in outputs if len(y) > k]
        if not usable:
            break
        squares = sum(float(torch.diff(y, n=k).square().sum()) for y in usable)
        variances.append(squares / (sum(len(y) - k for y in usable) * math.comb(2 * k, k)))
    return min(variances) if variances else 0.0


def noise_floor(records: Sequence[Record], scale: Sequence[Record] | None = None) -> float:
    """The noise floor (module docstring): the output noise read from ``records`` (from their repeats where they give
    it, else the lower of the readings by differences and from runs of repeats), as a fraction of the RMS of the
    outputs of ``scale`` (default ``records``): the records whose mismatch it is compared with. 0 for noise-free
    outputs."""
    scale = records if scale is None else scale
    shares = []
    for c in range(records[0].y.shape[1]):
        variance = _by_repeats(records, c)
        if variance is None:
            variance = _by_differences([r.y[:, c].detach().to(torch.float64) for r in records])
            runs = _by_repeated_runs(records, c)
            variance = variance if runs is None else min(variance, runs)
        scaled = [r.y[:, c].detach().to(torch.float64) for r in scale]
        power = float(sum(y.square().sum() for y in scaled)) / sum(len(y) for y in scaled)
        shares.append(variance / power if power > 0 else 0.0)
    return math.sqrt(sum(shares) / len(shares))
