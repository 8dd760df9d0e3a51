"""The tracker's filter against a linear Kalman filter written out in numpy, and against the model's own simulation;
a stream fed in blocks or one sample at a time gives the same sums bit for bit; refusals."""

import numpy as np
import pytest
import torch

from torchpaml import (RK4, ConfigurationError, FittedModel, Oscillator, Record, Tracker, pseudorandom, simulate,
                       time_grid, track)

H = 0.01


def _linear_record(noise: float, seed: int = 0, x0=(0.5, -0.3), u_scale: float = 0.0) -> tuple[FittedModel, Record]:
    t = time_grid(10.0, H)
    u = u_scale * pseudorandom(t, 1.0, seed=seed)
    physics = Oscillator(zeta=0.2, omega0=3.0, gain=2.0)
    with torch.no_grad():
        y = simulate(physics, t, u, torch.tensor([x0], dtype=torch.float64), solver=RK4(substeps=1))
    y = y + noise * torch.randn(y.shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
    return FittedModel(physics, RK4(substeps=1), step=H, noise=(noise,)), Record(t, u[0], y[0])


def _numpy_kalman(A: np.ndarray, C: np.ndarray, y: np.ndarray, x0, P0, R: float) -> tuple[np.ndarray, np.ndarray]:
    """The textbook Kalman filter of x' = A x, y = C x + v, discretised by one RK4 step per sample (its transition
    matrix I + hA + (hA)^2/2 + (hA)^3/6 + (hA)^4/24), no process noise: innovations and NIS."""
    hA = H * A
    F = np.eye(2) + hA + hA @ hA / 2 + hA @ hA @ hA / 6 + hA @ hA @ hA @ hA / 24
    x, P, innovations, nis = np.array(x0, dtype=float), np.array(P0, dtype=float), [], []
    for k in range(len(y)):
        if k:
            x, P = F @ x, F @ P @ F.T
        e = y[k] - C @ x
        S = C @ P @ C.T + R
        K = P @ C.T / S
        x = x + (K * e).ravel()
        P = (np.eye(2) - np.outer(K, C)) @ P @ (np.eye(2) - np.outer(K, C)).T + R * np.outer(K, K)
        innovations.append(float(e[0]))
        nis.append(float(e[0] ** 2 / S[0, 0]))
    return np.array(innovations), np.array(nis)


def test_the_filter_is_the_textbook_kalman_filter_on_linear_physics():
    """Oscillator (linear), a start at rest with prior variance 1 (the device is elsewhere), no process noise:
    innovations and NIS agree with a numpy Kalman filter to 1e-10 relative."""
    model, record = _linear_record(noise=0.01)
    tracker = Tracker(model, x0=(0.0, 0.0), initial_variance=1.0, process=(0.0, 0.0))
    tracking = tracker.feed(record)
    A, _, C, _ = model.physics.state_space()
    innovations, nis = _numpy_kalman(A.detach().numpy(), C.detach().numpy(), record.y.numpy(), (0.0, 0.0), np.eye(2), 0.01**2)
    assert np.allclose(tracking.innovation[:, 0], innovations, rtol=1e-10, atol=1e-13)
    window = tracker.samples
    sums = np.convolve(nis, np.ones(window))[: len(nis)]
    assert np.allclose(tracking.statistic, sums, rtol=1e-10, atol=1e-12)


def test_with_a_known_start_and_no_process_noise_the_innovation_is_the_output_error():
    """P = 0 stays 0: the filter runs the model open loop, so y - innovation is the model's own simulation."""
    model, record = _linear_record(noise=0.02, u_scale=1.0, x0=(0.0, 0.0))
    tracking = track(model, record, x0=(0.0, 0.0))
    assert np.allclose(record.y.numpy()[:, 0] - tracking.innovation[:, 0], model.simulate(record).numpy()[:, 0],
                       rtol=0, atol=1e-12)
    assert tracking.alarms == [] and tracking.innovation_rms["y"] == pytest.approx(0.02, rel=0.05)


def test_a_stream_fed_one_sample_at_a_time_gives_the_same_sums_and_alarms_as_one_block():
    model, record = _linear_record(noise=0.01, u_scale=1.0, x0=(0.0, 0.0))
    wrong = FittedModel(Oscillator(zeta=0.2, omega0=3.3, gain=2.0), RK4(substeps=1), step=H, noise=(0.01,))
    block = track(wrong, record)
    tracker = Tracker(wrong)
    alarms = [a for k in range(len(record.t)) if (a := tracker.update(float(record.t[k]), record.u[k].numpy(),
                                                                      record.y[k].numpy()))]
    alarms += tracker.flush()
    assert block.alarms and alarms == block.alarms  # the wrong omega0 is found, at the same sample, by both
    halves = Tracker(wrong)
    first, second = halves.feed(record.window(0, 333)), halves.feed(record.window(333, None))
    assert np.array_equal(np.concatenate([first.statistic, second.statistic]), block.statistic)


@pytest.mark.parametrize("options, message", [
    ({"noise": ()}, "needs each output's noise level"),
    ({"noise": (0.0,)}, "needs each output's noise level"),
    ({"window": 0.0}, "a window > 0 s"),
    ({"alpha": 1.5}, "0 < alpha < 1"),
])
def test_bad_settings_are_refused(options, message):
    model, _ = _linear_record(noise=0.01)
    with pytest.raises(ConfigurationError, match=message):
        Tracker(model, **options)
