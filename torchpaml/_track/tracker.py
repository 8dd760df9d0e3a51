r"""Tracking a running device: the model's Kalman filter, a change detector on its innovation, and the parameter
that moved.

**The filter** (:mod:`~torchpaml._track.filter_code`) runs on the fitted model, fed one sample or a block at a time,
the input held as ``hold`` says (default the model's). Its measurement noise $R$ is the diagonal of the model's
residual variance per output (``FittedModel.noise``, from the diagnosis). Where it starts and how far the model may
drift are taken from the stream and the fit (:mod:`~torchpaml._track.start`): by default the initial state is the
one that best explains the stream's first ``window`` seconds, with the covariance of that estimate, and the process
noise $Q$ is the state error that the fit's parameter uncertainty allows over the detector's window. ``x0`` starts it at a known
state instead (covariance ``initial_variance`` times the identity) and ``process`` gives each state's process
noise standard deviation per sample.

**A missing measurement** (NaN in an output) is predicted through and counted (``Tracking.missing``); a NaN or
infinite time or input is refused in one line.

**The detector** is a windowed chi-squared test: while the device matches the model, the normalised innovations
squared $\nu_k$ are independent $\chi^2_p$, so their sum over the last $W$ samples (``window`` seconds) is
$\chi^2_{pW}$. An alarm is raised where that sum crosses above its $1 - \alpha$ quantile (``alpha``, default
$10^{-9}$), once per crossing: the statistic must fall below its mean $pW$ before the next alarm. Every sample ends
a window, so at most $\alpha \cdot 3600/h$ false alarms an hour are expected at sampling interval $h$
(:attr:`Tracker.false_alarms_per_hour`, a union bound; ``benchmarks/bench_tracking.py`` measures the rate). With
the estimated start, the detector starts after the first window, whose samples made the start.

**The parameter that moved** is named once ``attribution`` seconds of the stream after the alarm have arrived (the
alarm keeps the time it was raised): the change is dated where the cumulative sum of $\nu_k - 2p$ over the $2W$
samples before the alarm is lowest, and on the samples from there to ``attribution`` seconds after the alarm, each
parameter the fit estimated (the learnable ones; every physical parameter where none is) is refitted alone, with the
state at the change, from the model's values
(:func:`~torchpaml.fit_physics`, Gauss-Newton on the parameters' sensitivities). The parameter whose refit explains the
samples best is named. At the end of a record (:func:`track`, :meth:`Tracker.flush`) an alarm is named on what
arrived.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import torch
from numpy.lib.stride_tricks import sliding_window_view
from scipy.stats import chi2

from torchpaml._data import Record
from torchpaml._errors import DataError
from torchpaml._fit.initial_state import Estimate
from torchpaml._grid import check_hold
from torchpaml._fit.physics_fit import fit_physics
from torchpaml._fit.uncertainty import IdentifiabilityWarning
from torchpaml._errors import ConfigurationError, TorchpamlError
from torchpaml._export.code import exported_step
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._model.prediction import check_channels
from torchpaml._track.filter_code import compiled_filter
from torchpaml._track.start import estimated_start, process_noise_of_fit, states_along

__all__ = ["Alarm", "Tracker", "Tracking", "track"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Alarm:
    """A change: the time (s) the statistic crossed its threshold, the statistic there, and the parameter that moved
    (``None`` where the samples around the alarm cannot tell: a constant output, a fit that fails)."""

    t: float
    statistic: float
    parameter: str | None


@dataclass
class Tracking:
    """What a tracker saw on a record (module docstring).

    Attributes:
        t: the sample times, (time,).
        innovation: $y - \\hat y^-$ at each sample, (time, n_y); NaN where the measurement is missing and on the
            samples of the estimated start.
        statistic: the sum of the normalised innovations squared over the last window, (time,).
        threshold: the statistic's alarm level.
        states: the filtered states, (time, n_state).
        alarms: the changes found.
        outputs: the output channels' names.
        seconds: the wall time of the filtering (and of naming the parameters at alarms).
        missing: the samples whose measurement was missing (NaN), predicted through.
        detector_from: the time (s) from which the detector judges the samples: after the first window where the
            start was estimated, else the stream's first sample.
        x0: the state the filter started from, (n_state,).
        process: the process noise's standard deviation per state and sample, $\\sqrt{\\operatorname{diag} Q}$.
        false_alarms_per_hour: the expected false alarms per hour at the detector's ``alpha`` (module docstring).
    """

    t: np.ndarray
    innovation: np.ndarray
    statistic: np.ndarray
    threshold: float
    states: np.ndarray
    alarms: list[Alarm] = field(default_factory=list)
    outputs: tuple[str, ...] = ()
    seconds: float = 0.0
    missing: int = 0
    detector_from: float | None = None
    x0: np.ndarray | None = None
    process: np.ndarray | None = None
    false_alarms_per_hour: float | None = None

    @property
    def innovation_rms(self) -> dict[str, float]:
        """The innovation's RMS per output channel."""
        judged = self.innovation[np.isfinite(self.innovation).all(axis=1)]
        return {name: float(np.sqrt(np.mean(judged[:, i] ** 2))) if len(judged) else float("nan")
                for i, name in enumerate(self.outputs)}


class Tracker:
    """The filter and the detector of one model, fed a stream (module docstring).

    Args:
        model: the fitted model (``torchpaml.load_model(path)``); a residual on top is not tracked.
        noise: each output's noise standard deviation; default the model's ``noise`` (the diagnosis' residual).
        process: each state's process noise standard deviation per sample; default from the fit's uncertainty
            (:func:`~torchpaml._track.start.process_noise_of_fit`; zero for a model without one).
        window: the detector's window, seconds; the start is estimated on the stream's first window.
        alpha: the detector's false-alarm probability per window.
        x0: a known initial state (default: estimated from the first window); ``initial_variance``: its variance,
            per state.
        step: the sampling interval, s (default the model's), which sets the window in samples.
        attribution: the seconds after an alarm on which the parameter that moved is named.
        hold: how the input moved between samples, ``"foh"`` or ``"zoh"`` (default the model's).
    """

    def __init__(self, model: FittedModel, *, noise: tuple[float, ...] | None = None,
                 process: tuple[float, ...] | None = None, window: float = 0.5, alpha: float = 1e-9,
                 x0: torch.Tensor | None = None, initial_variance: float = 0.0, step: float | None = None,
                 attribution: float = 1.0, hold: str | None = None):
        physics = model.physics
        n, m, p = physics.state_dim, physics.input_dim, physics.output_dim
        noise = tuple(model.noise) if noise is None else tuple(noise)
        if len(noise) != p or not all(np.isfinite(noise)) or min(noise) <= 0:
            raise ConfigurationError(f"tracking needs each output's noise level, {p} positive number(s), got {noise}: "
                                     "save the model from a diagnosis (which records its residual), or pass noise=")
        step = model.step if step is None else step
        if step is None or not step > 0 or not window > 0 or not 0 < alpha < 1:
            raise ConfigurationError(f"tracking needs a sampling interval (step={step}), a window > 0 s "
                                     f"(window={window}) and 0 < alpha < 1 (alpha={alpha})")
        self._x0 = None if x0 is None else _vector(x0, n, "x0", "the initial state, one value per state")
        if not (np.isfinite(initial_variance) and initial_variance >= 0):
            raise ConfigurationError(f"initial_variance is a variance >= 0, got {initial_variance}")
        self._process = None if process is None else _vector(process, n, "process", "each state's process noise "
                                                             "standard deviation per sample, >= 0", nonnegative=True)
        model = dataclasses.replace(model, residual=None, hold=check_hold(model.hold if hold is None else hold))
        step_map = exported_step(model)
        self.model, self.outputs, self.hold = model, tuple(model.outputs) or step_map.form.outputs, model.hold
        self.filter, self.substeps = compiled_filter(step_map), step_map.substeps
        self.step, self.alpha = float(step), float(alpha)
        self.samples = max(1, round(window / step))
        self.threshold = float(chi2.isf(alpha, p * self.samples))
        self.rearm = float(p * self.samples)
        self._noise, self._initial_variance = np.asarray(noise, dtype=np.float64), float(initial_variance)
        # the filter's arrays (filter_code.CompiledFilter.run_into): the last two samples' t, u, y, then x, P, Q, R,
        # and the two samples' innovation, nis and states; x and P carry the filter from one call to the next
        self._pair = (np.zeros(2), np.zeros((2, m)), np.zeros((2, p)), np.zeros(n), np.zeros((n, n)),
                      np.zeros((n, n)), np.diag(np.square(noise)), np.zeros((2, p)), np.zeros(2), np.zeros((2, n)))
        self._addresses = [a.ctypes.data for a in self._pair]
        self._run, self._sizes = self.filter.run_at_addresses(), (m, p)
        self._started = False
        self._waiting: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # samples before the start is known
        self._waited = 0
        self._armed = True
        self.missing = 0
        self.detector_from: float | None = None
        self.x0: np.ndarray | None = None
        self.after = max(1, round(attribution / step))
        self._history = _Ring(2 * self.samples + self.after + 1, (m, p, n))  # t, u, y, states, nis
        self._pending: list[tuple[int, float, float]] = []  # alarms to name: (sample in the stream, t, statistic)

    @property
    def false_alarms_per_hour(self) -> float:
        """The expected false alarms per hour of stream at ``alpha`` (module docstring): $\\alpha \\cdot 3600/h$."""
        return self.alpha * 3600.0 / self.step

    @property
    def Q(self) -> np.ndarray:
        """The process noise covariance per sample, (n_state, n_state) (zeros until the start is known)."""
        return self._pair[5]

    @property
    def x(self) -> np.ndarray:
        """The filtered state, (n_state,)."""
        return self._pair[3]

    @property
    def P(self) -> np.ndarray:
        """Its covariance, (n_state, n_state)."""
        return self._pair[4]

    def _begin(self, t: np.ndarray, u: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Set the filter's start from the first samples of the stream (module docstring); the outputs the filter
        reads, those of the estimated start's window missing (its samples made the start)."""
        first = slice(0, min(self.samples, len(t)))
        keep = np.isfinite(y[first]).all(axis=1)
        if self._x0 is None and keep.sum() < 2:
            raise DataError(f"the stream's first window (t = {t[0]:.6g} to {t[first][-1]:.6g} s) has fewer than two "
                            "measured samples to estimate the device's state from; give x0, or a stream that starts "
                            "with measurements")
        rows = np.nonzero(keep)[0] if self._x0 is None else np.arange(first.stop)
        window = Record(t[rows], u[rows], np.where(np.isfinite(y[rows]), y[rows], 0.0), "start", hold=self.hold)
        if self._x0 is None:
            x0, P0 = estimated_start(self.model, window, self._noise, self.substeps)
            y = y.copy()
            y[first] = np.nan
            self.detector_from = float(t[first][-1] + self.step)
        else:
            x0, P0 = self._x0, np.eye(len(self._x0)) * self._initial_variance
            self.detector_from = float(t[0])
        if self._process is not None:
            Q = np.diag(np.square(self._process))
        elif self.model.uncertainty is None:
            Q = np.zeros_like(P0)  # a model not saved from a fit: no uncertainty to drift by
        else:
            Q = process_noise_of_fit(self.model, states_along(self.model, window, x0, self.substeps), window,
                                     self.substeps, self.samples)
        self._pair[3][:], self._pair[4][:], self._pair[5][:] = x0, P0, Q
        self.x0 = x0.copy()
        log.info("tracking from t = %.6g s: %s start, process noise %s", t[0],
                 "estimated" if self._x0 is None else "given", "given" if self._process is not None else "of the fit")
        return y

    def _filter(self, t: np.ndarray, u: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, ...]:
        """Innovations, normalised innovations squared and filtered states of the new samples (after the stream's
        first, each is predicted from the sample before it, kept in the filter's arrays)."""
        pair, skip = self._pair, int(self._started)
        if skip:
            t, u, y = (np.concatenate([pair[i][1:], new]) for i, new in enumerate((t, u, y)))
        outputs = (np.zeros((len(t), y.shape[1])), np.zeros(len(t)), np.zeros((len(t), len(pair[3]))))
        self._check(self.filter.run_into(skip, (t, u, y, *pair[3:7], *outputs)), t)
        for i, array in enumerate((t, u, y)):
            pair[i][1] = array[-1]
        self._started = True
        return tuple(a[skip:] for a in outputs)

    def _check(self, failed: int, t: np.ndarray) -> None:
        if failed < 0:
            raise DataError(f"the input at t = {t[-failed - 1]:.6g} s is NaN or infinite; the filter cannot predict "
                            "without the input (a missing output is fine: give NaN)")
        if failed:
            raise ConfigurationError(f"the filter's innovation covariance stopped being positive definite at t = "
                                     f"{t[failed - 1]:.6g} s; raise the measurement noise (noise=)")

    def _statistic(self, nis: np.ndarray) -> np.ndarray:
        """The sum of the normalised innovations squared over the last window at each new sample (zeros before the
        stream's start), each window summed alone and in time order, so that a stream fed in blocks of any size,
        one sample included, gives the same sums bit for bit."""
        earlier = self._history.last(self.samples - 1)[4]
        values = np.concatenate([np.zeros(self.samples - 1 - len(earlier)), earlier, nis])
        return sliding_window_view(values, self.samples).sum(axis=1)

    def _alarms_at(self, statistic: np.ndarray) -> list[int]:
        """The samples where the statistic crosses above the threshold while armed (:meth:`_crosses`)."""
        return [int(k) for k in np.nonzero((statistic > self.threshold) | (statistic < self.rearm))[0]
                if self._crosses(statistic[k])]

    def _crosses(self, statistic: float) -> bool:
        """Whether ``statistic`` raises an alarm: above the threshold while armed. It re-arms where it falls back
        below its mean under no change, p W (the device matches the model again)."""
        if statistic > self.threshold and self._armed:
            self._armed = False
            return True
        if statistic < self.rearm:
            self._armed = True
        return False

    def update(self, t: float, u, y) -> Alarm | None:
        """One sample of a stream: its time (s), input (n_u,) and output (n_y,; NaN where missing); the alarm named
        on it, if any (raised ``attribution`` seconds earlier). The same filter, sums and decisions as :meth:`feed`,
        with the arrays kept between calls."""
        if not self._started:
            t, u, y = self._sample(t, u, y)
            alarms = self._advance(np.array([t]), u[None], y[None])[4]
            return alarms[0] if alarms else None
        times, inputs, outputs = self._pair[:3]  # the fast path: sizes checked here, a non-finite input by the C
        try:
            sizes = (len(u), len(y))
        except TypeError:
            sizes = None
        if sizes != self._sizes or not t > times[1]:
            self._sample(t, u, y)  # raises the one-line refusal
        times[0], inputs[0], outputs[0] = times[1], inputs[1], outputs[1]
        times[1], inputs[1], outputs[1] = t, u, y
        failed = self._run(2, 1, *self._addresses)
        if failed:
            self._check(failed, times)
        innovation = self._pair[7][1]
        self.missing += innovation[0] != innovation[0]  # NaN: the measurement was missing
        self._history.append((t, inputs[1], outputs[1], self._pair[9][1], self._pair[8][1]))
        statistic = self._history.window_sum(self.samples)
        if self._crosses(statistic):
            self._pending.append((self._history.count - 1, float(t), statistic))
        if not self._pending:
            return None
        named = self._named()
        return named[0] if named else None

    def _sample(self, t: float, u, y) -> tuple[float, np.ndarray, np.ndarray]:
        """One sample checked against the model: its input and output counts, a finite time and input."""
        u, y = np.asarray(u, dtype=np.float64).reshape(-1), np.asarray(y, dtype=np.float64).reshape(-1)
        m, p = self.model.physics.input_dim, self.model.physics.output_dim
        if len(u) != m or len(y) != p:
            raise DataError(f"a sample has {len(u)} input(s) and {len(y)} output(s); the model takes {m} input(s) and "
                            f"measures {p} output(s) ({', '.join(self.outputs)})")
        if not (np.isfinite(t) and np.isfinite(u).all()):
            raise DataError(f"a sample at t = {t} has a NaN or infinite time or input; the filter cannot predict "
                            "without the input (a missing output is fine: give NaN)")
        if self._started and not t > self._pair[0][1]:
            raise DataError(f"time must increase along a stream: t = {t:.6g} s follows {self._pair[0][1]:.6g} s")
        return float(t), u, y

    def feed(self, record: Record, end: bool = False) -> Tracking:
        """Filter the samples of ``record`` (the next part of a stream; its outputs may hold NaN where a measurement is
        missing) and return what was seen on them. Until the stream's first window has arrived, samples wait for the
        start to be estimated and are returned by the call that completes it; ``end=True`` says the stream ends with
        this record (the start is then estimated on what arrived)."""
        check_channels(self.model, record)
        log.info("tracking %d samples (%.6g s to %.6g s)", len(record.t), float(record.t[0]), float(record.t[-1]))
        started = time.perf_counter()
        t, u, y = (np.ascontiguousarray(v.numpy()) for v in (record.t, record.u, record.y))  # C reads them in order
        if self._started and not t[0] > self._pair[0][1]:
            raise DataError(f"record {record.name!r} starts at t = {t[0]:.6g} s, not after the stream's last sample "
                            f"({self._pair[0][1]:.6g} s); feed a stream's parts in time order")
        t, innovation, statistic, states, alarms = self._advance(t, u, y, end)
        return Tracking(t, innovation, statistic, self.threshold, states, alarms, self.outputs,
                        time.perf_counter() - started, self.missing, self.detector_from, self.x0,
                        np.sqrt(np.diag(self.Q)).copy() if self._started else None, self.false_alarms_per_hour)

    def _advance(self, t: np.ndarray, u: np.ndarray, y: np.ndarray, end: bool = False) -> tuple:
        if not self._started:
            self._waiting.append((t, u, y))
            self._waited += len(t)
            if self._waited < self.samples and self._x0 is None and not end:  # a known start needs no window
                p, n = y.shape[1], len(self._pair[3])
                return t[:0], np.zeros((0, p)), np.zeros(0), np.zeros((0, n)), []
            t, u, y = (np.concatenate(parts) for parts in zip(*self._waiting))
            self._waiting = []
            filtered = self._begin(t, u, y)
        else:
            filtered = y
        self.missing += int((~np.isfinite(y).all(axis=1)).sum())
        innovation, nis, states = self._filter(t, u, np.ascontiguousarray(filtered))
        statistic = self._statistic(nis)
        first = self._history.count
        alarms = []
        for k in self._alarms_at(statistic):
            self._pending.append((first + k, float(t[k]), float(statistic[k])))
        position = 0
        while position < len(t):  # up to each alarm's last sample, so that it is named on the samples it needs
            due = [index + self.after - first + 1 for index, _, _ in self._pending if index + self.after >= first]
            end_at = min([len(t)] + [d for d in due if d > position])
            self._history.extend(tuple(a[position:end_at] for a in (t, u, y, states, nis)))
            alarms += self._named()
            position = end_at
        return t, innovation, statistic, states, alarms

    def flush(self) -> list[Alarm]:
        """Name the alarms still waiting for their ``attribution`` seconds, on the samples that arrived (the end of a
        record). Samples still waiting for the start are filtered first, the start estimated on them."""
        alarms = []
        if self._waiting:
            alarms = self._advance(*(a[:0] for a in self._waiting[0]), end=True)[4]
        return alarms + self._named(final=True)

    def _named(self, final: bool = False) -> list[Alarm]:
        """The pending alarms whose ``attribution`` samples have arrived (all with ``final``), named."""
        done = [a for a in self._pending if final or self._history.count - 1 >= a[0] + self.after]
        self._pending = [a for a in self._pending if a not in done]
        recent = self._history.last(len(self._history)) if done else []
        start = self._history.count - len(self._history)  # the stream index of recent's first sample
        return [Alarm(t, statistic, self._moved(recent, index - start)) for index, t, statistic in done]

    def _moved(self, recent: list[np.ndarray], k: int) -> str | None:
        """The parameter that moved at the alarm at sample ``k`` of ``recent`` (t, u, y, states, nis; module
        docstring)."""
        t, u, y, states, nis = recent
        log.info("alarm at t = %.6g s: refitting the fitted parameters one at a time to name the one that moved", t[k])
        first = max(0, k - 2 * self.samples)
        begin = first + int(np.argmin(np.cumsum(nis[first: k + 1] - 2 * y.shape[1])))
        rows = begin + np.nonzero(np.isfinite(y[begin:k + self.after + 1]).all(axis=1))[0]  # the measured samples
        if len(rows) < 2:
            return None
        window = Record(t[rows], u[rows], y[rows], "alarm",
                        {"inputs": list(self.model.inputs)} if self.model.inputs else {}, self.hold)
        begin = int(rows[0])
        start = torch.from_numpy(states[begin].copy())
        physics = self.model.physics
        names = physics.learnable_names() or list(physics.physical_parameters())
        try:
            misfit = [self._refit(name, window, start) for name in names]
        except TorchpamlError:
            return None
        return names[int(np.argmin(misfit))]

    def _refit(self, name: str, window: Record, start: torch.Tensor) -> float:
        """The mismatch on ``window`` of the model with ``name`` alone refitted, from the state ``start``."""
        physics = copy.deepcopy(self.model.physics)
        physics.set_learnable(*physics.learnable_names(), learn=False).set_learnable(name)
        with warnings.catch_warnings():  # a parameter the window cannot determine keeps its value: its misfit
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            fit = fit_physics(physics, window, initial_state=Estimate(), start_states=[start],
                              solver=self.model.solver, max_nfev=20, ftol=1e-6)
        return fit.mismatch


class _Ring:
    """The last ``capacity`` samples of t, u, y, the filtered states and nis, kept in place (a stream fed one
    sample at a time writes one row). The nis are kept twice over, at ``i`` and ``i + capacity``, so that any
    window of the last ``capacity`` values is one contiguous slice (zeros before the stream's start)."""

    def __init__(self, capacity: int, widths: tuple[int, int, int]):
        m, p, n = widths
        self.capacity, self.count = capacity, 0
        self.arrays = [np.zeros(capacity), np.zeros((capacity, m)), np.zeros((capacity, p)), np.zeros((capacity, n)),
                       np.zeros(capacity)]
        self._nis = np.zeros(2 * capacity)

    def __len__(self) -> int:
        return min(self.count, self.capacity)

    def append(self, row: tuple) -> None:
        i = self.count % self.capacity
        for array, value in zip(self.arrays, row):
            array[i] = value
        self._nis[i] = self._nis[i + self.capacity] = row[4]
        self.count += 1

    def extend(self, blocks: tuple[np.ndarray, ...]) -> None:
        n = len(blocks[0])
        rows = min(n, self.capacity)
        index = (self.count + n - rows + np.arange(rows)) % self.capacity
        for array, block in zip(self.arrays, blocks):
            array[index] = block[n - rows:]
        self._nis[index] = self._nis[index + self.capacity] = blocks[4][n - rows:]
        self.count += n

    def last(self, n: int) -> list[np.ndarray]:
        """The last ``n`` rows of each array, oldest first (fewer where fewer were kept)."""
        n = min(n, len(self))
        index = (self.count - n + np.arange(n)) % self.capacity
        return [array[index] for array in self.arrays]

    def window_sum(self, n: int) -> float:
        """The sum of the last ``n`` (at most ``capacity``) nis in time order, zeros before the stream's start, as
        :meth:`Tracker._statistic` sums a window: the same numbers in the same order, so the same sum bit for bit."""
        end = self.count % self.capacity + self.capacity
        return float(self._nis[end - n:end].sum())


def _vector(value, n: int, name: str, meaning: str, nonnegative: bool = False) -> np.ndarray:
    """``value`` as a float64 vector of ``n`` finite numbers (``>= 0`` with ``nonnegative``); refused in one line."""
    array = np.asarray(torch.as_tensor(value, dtype=torch.float64).reshape(-1).numpy(), dtype=np.float64)
    if len(array) == 1 and n > 1 and nonnegative:
        array = np.repeat(array, n)  # one process noise for every state
    if len(array) != n or not np.isfinite(array).all() or (nonnegative and (array < 0).any()):
        raise ConfigurationError(f"{name} is {meaning}: {n} finite number(s) for the model's states, got "
                                 f"{array.tolist()}")
    return array


def track(model: FittedModel, record: Record, **options) -> Tracking:
    """Track ``model`` along ``record`` in one call (module docstring): ``Tracker(model, **options).feed(record,
    end=True)``, the alarms still waiting at the record's end named on what it holds."""
    tracker = Tracker(model, **options)
    tracking = tracker.feed(record, end=True)
    started = time.perf_counter()
    tracking.alarms += tracker.flush()
    tracking.seconds += time.perf_counter() - started
    return tracking
