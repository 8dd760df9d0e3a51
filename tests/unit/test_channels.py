"""Records with several channels: CSV headers both ways, and the check of the physics' channels at the door."""

import pytest
import torch

from two_mass import TRUTH, TwoMass
from torchpaml import (
    ChebyshevHammerstein,
    DataError,
    DomainError,
    Oscillator,
    Record,
    channel_mismatch,
    fit_chebyshev_hammerstein,
    fit_physics,
    mismatch,
    pseudorandom,
    simulate,
    time_grid,
)
from torchpaml.analysis import incompatibility_certificates
from torchpaml._certificates import draw_chebyshev


def _record(n_u: int, n_y: int, metadata: dict | None = None) -> Record:
    t = time_grid(1.0, 0.1)
    generator = torch.Generator().manual_seed(0)
    u, y = (torch.randn(len(t), n, generator=generator, dtype=torch.float64) for n in (n_u, n_y))
    return Record(t, u, y, "bench", metadata or {})


@pytest.mark.parametrize("n_u, n_y, header", [(1, 1, "t,u,y"), (2, 3, "t,u1,u2,y1,y2,y3"), (1, 2, "t,u,y1,y2")])
def test_csv_round_trip_with_numbered_channels(tmp_path, n_u, n_y, header):
    record = _record(n_u, n_y)
    path = record.to_csv(tmp_path / "r.csv")
    assert path.read_text().splitlines()[0] == header
    back = Record.from_csv(path)
    assert torch.equal(back.u, record.u) and torch.equal(back.y, record.y) and torch.equal(back.t, record.t)


def test_csv_round_trip_with_named_channels(tmp_path):
    record = _record(1, 2, {"inputs": ["force"], "outputs": ["x1", "x2"]})
    path = record.to_csv(tmp_path / "r.csv")
    assert path.read_text().splitlines()[1] == "t,force,x1,x2"
    back = Record.from_csv(path)
    assert back.metadata == record.metadata and torch.equal(back.y, record.y)


def test_a_named_channel_the_header_lacks_is_named(tmp_path):
    (tmp_path / "r.csv").write_text('# {"inputs": ["force"], "outputs": ["x1", "x2"]}\nt,force,x1\n0,1,2\n')
    with pytest.raises(DataError, match=r"missing column\(s\) \['x2'\]"):
        Record.from_csv(tmp_path / "r.csv")


def test_numbered_channels_are_read_in_the_order_of_their_numbers(tmp_path):
    (tmp_path / "r.csv").write_text("t,y2,u1,y10,y1\n0,2,5,10,1\n1,2,5,10,1\n")
    record = Record.from_csv(tmp_path / "r.csv")
    assert record.u.tolist() == [[5.0], [5.0]] and record.y[0].tolist() == [1.0, 2.0, 10.0]


def test_a_physics_given_records_with_other_channels_is_refused_in_one_line_naming_both_counts():
    t = time_grid(5.0, 0.05)
    u = pseudorandom(t, 1.0, seed=0)
    y = simulate(Oscillator(), t, u).detach()
    two_outputs = Record(t, u[0], torch.cat([y[0], y[0]], dim=1), "two")
    with pytest.raises(DataError) as error:
        fit_physics(Oscillator(), two_outputs)
    message = str(error.value)
    assert "\n" not in message
    assert message.startswith("record 'two' has 2 output channel(s), but Oscillator has 1 (output_dim)")


def test_names_that_do_not_fit_the_channels_are_refused_before_writing(tmp_path):
    record = _record(1, 2, {"inputs": ["force"], "outputs": ["x1"]})
    with pytest.raises(DataError, match=r"names 1 channel\(s\) \['x1'\] for the 2 columns of 'y'"):
        record.to_csv(tmp_path / "r.csv")
    assert not (tmp_path / "r.csv").exists()


def test_the_overall_mismatch_is_the_root_mean_square_of_the_channels():
    generator = torch.Generator().manual_seed(1)
    y = torch.randn(200, 2, generator=generator, dtype=torch.float64) * torch.tensor([1.0, 1000.0])
    y_model = y + torch.tensor([0.1, 10.0]) * torch.randn(200, 2, generator=generator, dtype=torch.float64)
    each = channel_mismatch(y, y_model)
    assert each.shape == (2,) and each[1] == pytest.approx(float((y - y_model)[:, 1].norm() / y[:, 1].norm()))
    assert mismatch(y, y_model) == pytest.approx(float(each.square().mean().sqrt()), rel=1e-14)
    assert mismatch(y[:, :1], y_model[:, :1]) == pytest.approx(float(each[0]), rel=1e-14)  # one channel: as ever


def test_the_residual_fits_two_outputs_each_with_its_own_numerators():
    t = time_grid(40.0, 0.05)
    u = pseudorandom(t, 1.0, 0.5, seed=3)
    truth = ChebyshevHammerstein(1.2, n=2, order=2, outputs=2)
    generator = torch.Generator().manual_seed(0)
    with torch.no_grad():
        truth.set_coefficients(torch.randn(2, 2, 3, generator=generator, dtype=torch.float64)
                               * torch.tensor([[[1.0]], [[100.0]]]))  # the second output 100 times the first
        target = truth(t, u)
    assert target.shape == (1, len(t), 2)
    fitted = ChebyshevHammerstein(1.2, n=2, order=2, outputs=2)
    assert fit_chebyshev_hammerstein(fitted, t, u, target).unexplained < 1e-6
    assert ChebyshevHammerstein(1.2, n=2, order=2).coefficients().shape == (2, 3)  # one output: as ever


def test_the_residual_takes_each_input_and_names_a_wrong_count():
    residual = ChebyshevHammerstein(1.0, n=3, inputs=2)
    t = time_grid(1.0, 0.1)
    u = torch.stack([torch.full_like(t, 0.5), torch.full_like(t, -0.5)], dim=-1)[None]
    assert residual.features(u).shape == (1, len(t), 6)
    with pytest.raises(DomainError, match="takes 2 input channel"):
        residual.features(u[..., :1])


def test_certificates_hold_against_both_outputs_and_every_sensitivity_of_a_two_mass_chain():
    physics = TwoMass(**TRUTH)
    zeroth, first = incompatibility_certificates(
        physics, lambda g: draw_chebyshev(1.0, g, outputs=2), alpha=1.0, parameter=list(TRUTH), duration=240.0,
        draws=3, samples_per_period=200).worst
    # the single-channel tolerance (tests/unit/test_certificates.py), past the chain's slower transient (decay ~0.1 1/s)
    assert zeroth < 1e-3 and first < 1e-3


class _Named(Oscillator):
    output_names = ("position",)


def test_a_record_whose_channel_names_differ_from_the_physics_is_named_in_one_line():
    t = time_grid(10.0, 0.1)
    u = pseudorandom(t, 1.0, 0.5, seed=0)
    with torch.no_grad():
        y = simulate(_Named(), t, u)[0]
    named = Record(t, u[0], y, "bench", {"outputs": ["angle"]})
    with pytest.raises(DataError, match=r"names its outputs \['angle'\], but _Named names them \['position'\]"):
        fit_physics(_Named(), named)
    assert fit_physics(_Named(), Record(t, u[0], y, "bench", {"outputs": ["position"]})).mismatch < 1e-6
