"""Records with several channels: CSV headers both ways, and the check of the physics' channels at the door."""

import pytest
import torch

from torchpaml import DataError, Oscillator, Record, fit_physics, pseudorandom, simulate, time_grid


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
