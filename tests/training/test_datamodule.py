"""The data module: sources, windows with washout, batching rules and their errors."""

import pytest
import torch

from torchpaml import DataError, Record, RecordDataModule, Files, Oscillator, Simulated


def truth():
    return Oscillator(zeta=0.4, omega0=2.0, learn=())


def test_simulated_source_is_seeded_and_adds_the_requested_noise():
    clean = Simulated(truth(), "pseudorandom", amplitude=1.0, seeds=[3], duration=10.0).experiments()[0]
    noisy = Simulated(truth(), "pseudorandom", amplitude=1.0, seeds=[3], duration=10.0, noise=0.02).experiments()
    again = Simulated(truth(), "pseudorandom", amplitude=1.0, seeds=[3], duration=10.0, noise=0.02).experiments()
    assert torch.equal(noisy[0].y, again[0].y)
    relative = float((noisy[0].y - clean.y).pow(2).mean().sqrt() / clean.y.pow(2).mean().sqrt())
    assert relative == pytest.approx(0.02, rel=0.1)  # 1000 samples: the sample std is within ~5 %


def test_windows_skip_the_washout_and_tile_the_record():
    data = RecordDataModule(Simulated(truth(), "sine", duration=10.0), window=2.0, washout=1.0)
    items = data.items("train")
    assert len(items) == 4  # windows start at 1, 3, 5, 7 s; each simulated from 1 s earlier
    assert all(item["washout"] == 100 and len(item["t"]) == 300 for item in items)
    record = data.records("train")[0]
    assert torch.equal(items[1]["y"], record.y[200:500])
    assert float(items[1]["t"][0]) == 0.0
    whole = data.full_batch("train")
    assert whole["u"].shape == (1, 1000, 1) and whole["washout"] == 0


def test_a_window_longer_than_the_record_is_an_error():
    data = RecordDataModule(Simulated(truth(), "sine", duration=5.0), window=4.0, washout=2.0)
    with pytest.raises(DataError, match="shorter than window \\+ washout"):
        data.items("train")


def test_records_on_different_grids_cannot_share_a_batch(tmp_path):
    t = torch.arange(100, dtype=torch.float64) * 0.01
    Record(t, torch.sin(t), torch.cos(t), "a").to_csv(tmp_path / "a.csv")
    Record(t[:50], torch.sin(t[:50]), torch.cos(t[:50]), "b").to_csv(tmp_path / "b.csv")
    data = RecordDataModule(Files([str(tmp_path / "a.csv"), str(tmp_path / "b.csv")]))
    with pytest.raises(DataError, match="different time grids.*batch_size: 1"):
        next(iter(data.train_dataloader()))
    assert len(list(RecordDataModule(Files([str(tmp_path / "a.csv"), str(tmp_path / "b.csv")]),
                                     batch_size=1).train_dataloader())) == 2


def test_file_sources_name_the_problem():
    with pytest.raises(DataError, match="unknown file type '.txt'"):
        Files(["record.txt"]).experiments()
    with pytest.raises(DataError, match="at least one path"):
        Files([])
    with pytest.raises(DataError, match="test split is empty"):
        RecordDataModule(Simulated(truth(), duration=5.0)).test_dataloader()


def test_a_zero_order_hold_record_is_refused_by_the_lightning_systems_data(tmp_path):
    t = torch.arange(20, dtype=torch.float64) * 0.1
    path = Record(t, torch.sin(t), torch.cos(t), "held", {"hold": "zoh"}).to_csv(tmp_path / "held.csv")
    with pytest.raises(DataError, match="hold their input constant between samples"):
        RecordDataModule(Files([str(path)])).records("train")
