"""``torchpaml diagnose`` on a device with several sensors, as a new user meets it: each mistake ends with exit 2 in at
most three lines that name it, and several records of one length or of unequal lengths work on every path.

The device is a user's two-cart physics that names its channels (``input_names = ("force",)``, ``output_names =
("pos_a", "pos_b")``), with Coulomb friction on the second cart, measured at 20 Hz for 24 s with 2 % noise.
"""

import json
import sys
import textwrap

import pytest
import torch

from two_mass import FRICTION, TRUTH
from torchpaml import CoulombFriction, Record, Simulated, build_model
from torchpaml.cli import main

pytestmark = pytest.mark.slow  # runs the command line end to end: the slow lane

CART = textwrap.dedent('''
    from two_mass import TwoMass


    class TwoCart(TwoMass):
        """The two-mass chain with named channels."""

        input_names = ("force",)
        output_names = ("pos_a", "pos_b")


    class MisnamedCart(TwoCart):
        """A mistake: a degree of freedom whose velocity is not a state."""

        degrees_of_freedom = (("x1", "v1"), ("x2", "vB"))
''')
CONFIG = "physics: {class_path: cart.TwoCart}\neffects: [coulomb_friction]\n"


def written(record: Record, path, change=None, metadata=None):
    """``record`` as a CSV at ``path``, after ``change(t, u, y)`` (copies) where given."""
    t, u, y = record.t.clone(), record.u.clone(), record.y.clone()
    if change is not None:
        change(t, u, y)
    Record(t, u, y, record.name, metadata or {}).to_csv(path)
    return path


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """The user's module, config and records: train.csv, val.csv (y1, y2 headers) and the mistakes' variants."""
    folder = tmp_path_factory.mktemp("cart")
    (folder / "cart.py").write_text(CART)
    (folder / "cart.yaml").write_text(CONFIG)
    from two_mass import TwoMass

    device = TwoMass(**TRUTH, learn=()) + CoulombFriction(FRICTION).on("v2")
    train, validation = (Simulated(device, signal, 1.0, [seed], 24.0, 0.05, noise=0.02).experiments()[0]
                         for signal, seed in (("pseudorandom", 0), ("multisine", 1)))
    written(train, folder / "train.csv")
    written(validation, folder / "val.csv")
    written(train, folder / "dead.csv", lambda t, u, y: y[:, 1].zero_())
    written(train, folder / "ms_train.csv", lambda t, u, y: t.mul_(1000))
    written(validation, folder / "ms_val.csv", lambda t, u, y: t.mul_(1000))
    written(train, folder / "mm_train.csv", lambda t, u, y: y[:, 1].mul_(1000))
    rows = (folder / "train.csv").read_text().splitlines()
    cells = rows[8].split(",")
    cells[3] = "nan"  # y2 at row 7
    (folder / "nan.csv").write_text("\n".join([*rows[:8], ",".join(cells), *rows[9:]]) + "\n")
    named = written(train, folder / "named.csv", metadata={"inputs": ["force"], "outputs": ["pos_a", "pos_b"]})
    (folder / "logger.csv").write_text("\n".join(named.read_text().splitlines()[1:]) + "\n")  # no metadata line
    (folder / "sub").mkdir()
    (folder / "sub" / "paths.yaml").write_text(CONFIG + "data: ../missing.csv\nvalidation: ../val.csv\n")
    return folder


def diagnose_cli(folder, monkeypatch, capsys, *args):
    """``torchpaml diagnose ARGS`` in-process from ``folder``: (exit status, stdout, stderr)."""
    monkeypatch.chdir(folder)
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setattr(sys, "argv", ["torchpaml", "diagnose", "--quiet", *args])
    try:
        main()
        status = 0
    except SystemExit as exit_:
        status = exit_.code
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.mark.parametrize("args, words", [
    (["--data", "dead.csv"], ["output channel 'y2'", "is constant", "dead sensor"]),
    (["--config", "misnamed.yaml"], ["degrees_of_freedom names state(s) ['vB']",
                                     "its states are ['x1', 'x2', 'v1', 'v2']"]),
    (["--data", "ms_train.csv", "--validation", "ms_val.csv"], ["sampled every 50 s", "give t in seconds",
                                                              "milliseconds"]),
    (["--data", "mm_train.csv"], ["output 'y2'", "times smaller", "another unit",
                                  "give every record's 'y2' in one unit"]),
    (["--data", "nan.csv"], ["column 'y2' has 1 NaN/inf value(s), first at row 7"]),
])
def test_each_mistake_exits_2_in_at_most_three_lines_that_name_it(folder, monkeypatch, capsys, args, words):
    (folder / "misnamed.yaml").write_text(CONFIG.replace("cart.TwoCart", "cart.MisnamedCart"))
    if "--config" not in args:
        args = ["--config", "cart.yaml", *args]
    defaults = {"--data": "train.csv", "--validation": "val.csv", "--out": "out"}
    args = [*args, *(item for key, value in defaults.items() if key not in args for item in (key, value))]
    status, out, err = diagnose_cli(folder, monkeypatch, capsys, *args)
    assert status == 2, out + err
    assert len(err.strip().splitlines()) <= 3, err
    for word in words:
        assert word in err, err


def test_a_loggers_header_is_read_by_the_channels_the_physics_names(folder, monkeypatch, capsys):
    status, out, err = diagnose_cli(folder, monkeypatch, capsys, "--config", "cart.yaml", "--data", "logger.csv",
                                    "--validation", "val.csv", "--out", "named_out")
    assert status == 0, err
    report = json.loads((folder / "named_out" / "diagnosis.json").read_text())
    assert report["ladder"][-1]["model"] == "TwoCart + coulomb_friction_v2"
    assert [c["name"] for c in report["where_it_fails"]["channels"]] == ["pos_a", "pos_b"]


def test_a_loggers_header_that_the_physics_does_not_name_shows_the_line_that_names_it(folder, monkeypatch, capsys):
    status, out, err = diagnose_cli(folder, monkeypatch, capsys, "--physics", "oscillator", "--data", "logger.csv",
                                    "--validation", "val.csv", "--out", "out")
    assert status == 2 and len(err.strip().splitlines()) <= 3, err
    assert "missing column(s) ['u', 'y']" in err and '# {"inputs": ["force"], "outputs": ["pos_a", "pos_b"]}' in err


def test_a_record_path_in_a_config_that_names_no_file_says_which_folder_it_read(folder, monkeypatch, capsys):
    status, out, err = diagnose_cli(folder, monkeypatch, capsys, "--config", "sub/paths.yaml", "--out", "out")
    assert status == 2 and len(err.strip().splitlines()) <= 3, err
    assert f"no such file: {folder / 'sub' / '../missing.csv'}" in err


def test_record_paths_in_a_config_are_read_from_the_configs_folder(folder, monkeypatch, capsys, tmp_path):
    (folder / "sub" / "found.yaml").write_text(CONFIG + "data: ../train.csv\nvalidation: ../val.csv\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.syspath_prepend(str(folder))
    status, out, err = diagnose_cli(elsewhere, monkeypatch, capsys, "--config", str(folder / "sub" / "found.yaml"),
                                    "--out", "out")
    assert status == 0, err
    assert (elsewhere / "out" / "diagnosis.json").is_file()


def oscillator_records(folder):
    """A linear oscillator's records with Coulomb friction: two training records of unequal lengths and two
    validation records of one length (30 s, 20 s; 20 s each, at 20 Hz)."""
    device = build_model("oscillator", {"zeta": 0.2, "gain": 4.0}, {"coulomb_friction": 0.5})
    names = []
    for signal, seed, duration, name in (("pseudorandom", 0, 30.0, "a"), ("pseudorandom", 2, 20.0, "b"),
                                         ("multisine", 1, 20.0, "v1"), ("multisine", 3, 20.0, "v2")):
        (record,) = Simulated(device, signal, 1.0, [seed], duration, 0.05, noise=0.02).experiments()
        names.append(str(record.to_csv(folder / f"{name}.csv")))
    return names


def test_several_records_of_one_length_and_of_unequal_lengths_on_every_path(monkeypatch, capsys, tmp_path):
    """Ranking, ladder, hybrid, discovery and report: training records of unequal lengths, validation records of one
    length (the hybrid once stacked the physics' outputs of such records end to end: a shape error)."""
    a, b, v1, v2 = oscillator_records(tmp_path)
    status, out, err = diagnose_cli(tmp_path, monkeypatch, capsys, "--physics", "oscillator", "--effect",
                                    "coulomb_friction", "--effect", "quadratic_damping", "--data", a, b,
                                    "--validation", v1, v2, "--discover", "--out", "out")
    assert status == 0, err
    report = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert report["ladder"][-1]["model"] == "Oscillator + coulomb_friction"
    first, last = report["hybrid"]
    assert all(torch.isfinite(torch.tensor(h["nrmse_validation"])) for h in (first, last)), report["hybrid"]
    assert first["inadequate"] and last["message"].startswith("physics complete"), report["hybrid"]
    assert (tmp_path / "out" / "discovery.json").is_file() and (tmp_path / "out" / "report.html").is_file()
