"""The tracker's filter against a linear Kalman filter written out in numpy, and against the model's own simulation;
a stream fed in blocks or one sample at a time gives the same sums bit for bit; refusals."""

import numpy as np
import pytest
import torch

from torchpaml import (RK4, ConfigurationError, DataError, FittedModel, Oscillator, Record, Tracker, fit_physics,
                       pseudorandom, simulate, time_grid, track)

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


def _two_output_model() -> FittedModel:
    from two_mass import TwoMass

    return FittedModel(TwoMass(), RK4(substeps=1), step=H, noise=(0.01, 0.01), inputs=("u",), outputs=("x1", "x2"))


@pytest.mark.parametrize("outputs", [1, 3])
def test_a_stream_with_another_number_of_outputs_is_refused_in_one_line_before_any_c_runs(outputs, monkeypatch):
    """A two-output model on a stream of one or three outputs: the record check refuses it (the filter would write
    past its buffer), in feed and in update."""
    model = _two_output_model()
    t = time_grid(2.0, H)
    record = Record(t, pseudorandom(t, 1.0, seed=0)[0], torch.zeros(len(t), outputs))
    tracker = Tracker(model)
    monkeypatch.setattr(tracker.filter, "run_into", lambda *a: pytest.fail("the filter ran on a wrong stream"))
    with pytest.raises(DataError, match=rf"has {outputs} output channel\(s\), but TwoMass has 2") as refused:
        tracker.feed(record)
    assert "\n" not in str(refused.value)
    with pytest.raises(DataError, match=rf"a sample has 1 input\(s\) and {outputs} output\(s\); the model .* 2 "):
        tracker.update(0.0, [0.0], [0.0] * outputs)


def test_a_missing_measurement_is_predicted_through_and_counted():
    """NaN outputs (one sample in ten, and a run of 50): the state stays finite, the innovation is NaN exactly there,
    the detector raises no alarm, the same as a stream without those samples would; fed one sample at a time too."""
    model, record = _linear_record(noise=0.01, u_scale=1.0, x0=(0.3, -0.2))
    y = record.y.clone()
    gaps = (torch.arange(len(y)) % 10 == 7) | ((torch.arange(len(y)) >= 600) & (torch.arange(len(y)) < 650))
    y[gaps] = float("nan")
    stream = Record(record.t, record.u, y, metadata={"missing_outputs": int(gaps.sum())})
    tracking = track(model, stream)
    assert tracking.missing == int(gaps.sum()) and tracking.alarms == []
    assert np.isfinite(tracking.states).all() and np.isfinite(tracking.statistic).all()
    judged = np.arange(len(y)) >= tracker_start(model)
    assert np.array_equal(np.isnan(tracking.innovation[judged, 0]), gaps.numpy()[judged])
    one_by_one = Tracker(model)
    for k in range(len(y)):
        one_by_one.update(float(stream.t[k]), stream.u[k].numpy(), stream.y[k].numpy())
    assert one_by_one.missing == tracking.missing and np.array_equal(one_by_one.x, tracking.states[-1])


def tracker_start(model: FittedModel) -> int:
    """The samples of the estimated start (the detector's window at the default 0.5 s)."""
    return Tracker(model).samples


def test_a_missing_input_or_time_is_refused_and_a_fit_refuses_missing_outputs():
    model, record = _linear_record(noise=0.01)
    tracker = Tracker(model)
    with pytest.raises(DataError, match="NaN or infinite time or input"):
        tracker.update(0.0, [float("nan")], [0.0])
    y = record.y.clone()
    y[5] = float("nan")
    gappy = Record(record.t, record.u, y, metadata={"missing_outputs": 1})
    with pytest.raises(DataError, match=r"1 sample\(s\) whose output is missing"):
        fit_physics(Oscillator(), gappy)
    with pytest.raises(DataError, match="NaN/inf"):
        Record(record.t, record.u, y)  # without the metadata a NaN is a mistake, as before


def test_a_stream_csv_with_empty_output_cells_is_read_for_tracking(tmp_path):
    model, record = _linear_record(noise=0.01, u_scale=1.0)
    record.to_csv(tmp_path / "stream.csv")
    lines = (tmp_path / "stream.csv").read_text().splitlines()
    lines[10] = lines[10].rsplit(",", 1)[0] + ","  # a sample whose output did not arrive: an empty cell
    lines[11] = lines[11].rsplit(",", 1)[0] + ",nan"
    (tmp_path / "stream.csv").write_text("\n".join(lines) + "\n")
    stream = Record.from_csv(tmp_path / "stream.csv", missing_outputs=True)
    first = 10 - 1 - int(lines[0].startswith("#"))  # the rows above the samples: the header, a metadata line
    assert stream.metadata["missing_outputs"] == 2
    assert torch.isnan(stream.y[:, 0]).nonzero().flatten().tolist() == [first, first + 1]
    with pytest.raises(DataError, match="not a number"):
        Record.from_csv(tmp_path / "stream.csv")


def test_the_hold_is_the_trackers_own():
    """A zero-order-hold stream tracked with hold='zoh' matches the model's own zoh simulation (innovation = y - model
    output on a known start); with the model's foh it does not."""
    model, record = _linear_record(noise=0.0, u_scale=1.0, x0=(0.0, 0.0))
    held = Record(record.t, record.u, record.y, hold="zoh")
    y = model.simulate(held)
    exact = Record(record.t, record.u, y, hold="zoh")
    zoh = track(model, exact, x0=(0.0, 0.0), hold="zoh", noise=(0.01,))
    foh = track(model, exact, x0=(0.0, 0.0), noise=(0.01,))
    assert np.abs(zoh.innovation).max() < 1e-12 < np.abs(foh.innovation).max()
