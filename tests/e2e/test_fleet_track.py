"""``torchpaml track --units``: a fleet of three devices, each tracked on its own ``model.pt`` on a local Ray; the
table names the one unit that changed and the parameter that moved, a unit with a bad stream gets its error and the
fleet goes on. Skipped without Ray (``pip install 'torchpaml[fleet]'``)."""

import copy
import json

import pytest
import torch

from torchpaml import (RK4, CoulombFriction, FittedModel, Oscillator, Record, pseudorandom, save_model, time_grid)
from torchpaml.cli import main

pytestmark = pytest.mark.slow  # Ray's start: the slow lane
pytest.importorskip("ray", reason="torchpaml track --units needs the extra: pip install 'torchpaml[fleet]'")

H, DURATION, CHANGE, NOISE = 0.01, 20.0, 10.0, 0.01
LEARN = ("zeta", "omega0", "gain")


def _unit(folder, physics, changed, seed: int) -> None:
    """A unit folder: its model (the physics as fitted) and a stream that starts in motion; ``changed`` from CHANGE."""
    t = time_grid(3.0 + DURATION, H)
    u = pseudorandom(t, 1.0, seed=seed)
    k, first = round((3.0 + CHANGE) / H), round(3.0 / H)
    with torch.no_grad():
        before = RK4(substeps=2).states(physics, t[: k + 1], u[:, : k + 1], physics.initial_state(1))
        after = RK4(substeps=2).states(changed, t[k:], u[:, k:], before[:, -1])
        y = torch.cat([physics.output(before, u[:, : k + 1]), changed.output(after[:, 1:], u[:, k + 1:])], 1)[0]
    y = y[first:] + NOISE * torch.randn(y[first:].shape, generator=torch.Generator().manual_seed(seed),
                                        dtype=torch.float64)
    folder.mkdir(parents=True)
    save_model(FittedModel(physics, RK4(substeps=2), step=H, noise=(NOISE,)), folder / "model.pt")
    Record(t[first:] - t[first], u[0, first:], y).to_csv(folder / "stream.csv")


def test_a_fleet_is_tracked_on_ray_and_the_table_names_the_unit_that_changed(tmp_path, monkeypatch, capsys):
    physics = Oscillator(zeta=0.1, omega0=5.0, gain=25.0, learn=LEARN) + CoulombFriction(1.0)
    doubled = copy.deepcopy(physics).assign(**{"coulomb_friction.Fc": 2.0})
    units = tmp_path / "units"
    _unit(units / "a", physics, physics, 1)
    _unit(units / "b", physics, doubled, 2)
    _unit(units / "c", physics, physics, 3)
    (units / "d").mkdir()
    (units / "d" / "stream.csv").write_text("t,u,y\n0,0,0\n")  # no model.pt: its error, the fleet goes on
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.argv", ["torchpaml"])
    main(["track", "--units", "units", "--out", "out", "--workers", "2", "--quiet"])
    fleet = json.loads((tmp_path / "out" / "fleet_track.json").read_text())
    rows = {row["unit"]: row for row in fleet["units"]}
    assert [rows[u]["changed"] for u in "abc"] == [False, True, False]
    first = rows["b"]["alarms"][0]
    assert CHANGE <= first["t"] <= CHANGE + 2.0 and first["parameter"] == "coulomb_friction.Fc"
    assert rows["d"]["error"] and "no model file" in rows["d"]["error"]
    assert (tmp_path / "out" / "b" / "track.json").is_file()
    table = (tmp_path / "out" / "fleet_track.md").read_text()
    assert "| b | yes |" in table and "coulomb_friction.Fc" in table and "| a | no |" in table
    assert "changed: ['b']" in capsys.readouterr().out


def test_per_device_options_are_refused_with_units(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("sys.argv", ["torchpaml"])
    with pytest.raises(SystemExit) as stop:
        main(["track", "--units", str(tmp_path), "--out", str(tmp_path / "out"), "--noise", "0.1"])
    assert stop.value.code == 2 and "drop --noise" in capsys.readouterr().err
