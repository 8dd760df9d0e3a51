"""Record I/O round trips."""

import pytest
import torch

from torchpaml import DataError, Oscillator, Record, simulate


def _experiment():
    t = torch.arange(50, dtype=torch.float64) * 0.1
    return Record(t, torch.sin(t), torch.cos(t), name="demo", metadata={"alpha": 4.0, "seed": 1})


def test_csv_round_trip_is_exact(tmp_path):
    original = _experiment()
    loaded = Record.from_csv(original.to_csv(tmp_path / "demo.csv"))
    assert torch.equal(loaded.t, original.t) and torch.equal(loaded.u, original.u) and torch.equal(loaded.y, original.y)
    assert loaded.metadata == original.metadata and loaded.name == "demo"
    assert (tmp_path / "demo.csv").read_text().splitlines()[1] == "t,u,y"


def test_npz_round_trip_is_exact(tmp_path):
    original = _experiment()
    loaded = Record.from_npz(original.to_npz(tmp_path / "demo.npz"))
    assert torch.equal(loaded.y, original.y) and loaded.metadata == original.metadata


def test_batch_shapes_and_dt():
    t, u, y = _experiment().batch()
    assert t.shape == (50,) and u.shape == (1, 50, 1) and y.shape == (1, 50, 1)
    assert abs(_experiment().dt - 0.1) < 1e-12


def test_hold_is_checked_read_from_metadata_and_kept_by_windows(tmp_path):
    t = torch.arange(10, dtype=torch.float64) * 0.1
    with pytest.raises(ValueError, match="hold must be 'foh'"):
        Record(t, t, t, hold="linear")
    path = Record(t, t, t, "held", {"hold": "zoh"}).to_csv(tmp_path / "held.csv")
    record = Record.from_csv(path)
    assert record.hold == "zoh"
    for written in (Record(t, t, t, hold="zoh").to_csv(tmp_path / "a.csv"),
                    Record(t, t, t, hold="zoh").to_npz(tmp_path / "a.npz")):  # a file keeps the hold
        reader = Record.from_csv if written.suffix == ".csv" else Record.from_npz
        assert reader(written).hold == "zoh"
    assert Record.from_csv(path, hold="foh").hold == "foh"  # the argument wins over the metadata
    part = record.window(2, 6, "part")
    assert (part.hold, part.name, len(part.t)) == ("zoh", "part", 4)


@pytest.mark.parametrize("line, says", [('# {"signal": "pseudorandom", "seed": 0', "not JSON"),
                                        ("# measured on the bench", "not JSON"),
                                        ("# [1, 2]", "must be a JSON object")])
def test_a_metadata_line_that_is_not_a_json_object_is_refused_by_name(tmp_path, line, says):
    """A CSV whose first line starts with '#' but is not a JSON object (a column deleted with a spreadsheet, a
    free-text note) is a DataError that names the line and the fix, not an internal error."""
    path = tmp_path / "record.csv"
    path.write_text(f"{line}\nt,u,y\n0,0,0\n0.1,1,0.5\n")
    with pytest.raises(DataError, match=f"first line.*{says}.*repair it or delete the line"):
        Record.from_csv(path)


@pytest.mark.parametrize("where", ["u", "x0"])
def test_simulate_names_a_nan_input_instead_of_a_blow_up(where):
    """A NaN in the input or the initial state is the data's fault: a DataError naming it and where, not a
    SimulationError that blames the parameters."""
    t = torch.arange(300, dtype=torch.float64) * 0.05
    u = torch.sin(t)[None, :, None]
    x0 = torch.zeros(1, 2, dtype=torch.float64)
    if where == "u":
        u = u.clone()
        u[0, 17, 0] = float("nan")
    else:
        x0[0, 1] = float("inf")
    with pytest.raises(DataError, match=rf"{where} has 1 NaN/inf value\(s\), first at index \[0, {17 if where == 'u' else 1}"):
        simulate(Oscillator(), t, u, x0)
