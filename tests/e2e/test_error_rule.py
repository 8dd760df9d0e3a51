"""The command line's error rule: a user's mistake is one line and exit 2; a bug in the library is its traceback."""

import pytest

import torchpaml.cli.diagnose
from torchpaml import ConfigurationError, TorchpamlError
from torchpaml.cli import main

pytestmark = pytest.mark.slow


def _diagnose(capsys, monkeypatch, *extra: str) -> tuple[int, str]:
    monkeypatch.setattr("sys.argv", ["torchpaml"])
    argv = ["diagnose", "--data", "train.csv", "--validation", "validation.csv", "--physics", "oscillator",
            "--out", "out", *extra]
    with pytest.raises(SystemExit) as stop:
        main(argv)
    return stop.value.code, capsys.readouterr().err


def test_a_user_mistake_is_one_line_and_exit_2(capsys, monkeypatch):
    code, err = _diagnose(capsys, monkeypatch, "--shortlist", "0")
    assert code == 2
    assert err.strip().splitlines() == [err.strip()]
    assert err.startswith("torchpaml diagnose: error: --shortlist must be at least 1")


def test_an_unexpected_exception_in_the_library_reaches_the_user_with_its_traceback(capsys, monkeypatch):
    def broken(argv, prog):
        return {}["a key the library forgot"]

    monkeypatch.setattr(torchpaml.cli.diagnose, "run_diagnose", broken)
    code, err = _diagnose(capsys, monkeypatch)
    assert code == 1
    assert "Traceback (most recent call last)" in err and "KeyError" in err and "in broken" in err
    assert err.strip().splitlines()[-1].startswith("torchpaml diagnose: internal error: KeyError is a bug in torchpaml")


def test_every_typed_error_is_of_the_family_and_keeps_its_builtin_base():
    assert issubclass(ConfigurationError, TorchpamlError)
    assert issubclass(ConfigurationError, ValueError) and issubclass(ConfigurationError, TypeError)


def test_a_value_the_physics_refuses_in_a_config_is_one_line_naming_the_class_and_the_rule(tmp_path, capsys,
                                                                                          monkeypatch):
    config = tmp_path / "config.yaml"
    config.write_text("physics:\n  class_path: torchpaml.Oscillator\n  init_args:\n    zeta: -1\n")
    code, err = _diagnose(capsys, monkeypatch, "--config", str(config))
    assert code == 2
    assert err.strip() == ("torchpaml diagnose: error: config class_path torchpaml.Oscillator: parameter 'zeta' must be "
                           "positive and finite, got -1.0; pass a value > 0")


def test_a_physics_with_two_outputs_given_records_with_one_is_one_line_naming_both_counts(tmp_path, capsys,
                                                                                          monkeypatch):
    from torchpaml import Oscillator, Record, pseudorandom, simulate, time_grid

    (tmp_path / "two_outputs.py").write_text(
        "from torchpaml import Oscillator\n\n\n"
        "class TwoOutputs(Oscillator):\n"
        "    output_dim = 2\n\n"
        "    def output(self, x, u):\n"
        "        return x\n")
    t = time_grid(10.0, 0.05)
    for name, seed in (("train", 0), ("validation", 1)):
        u = pseudorandom(t, 1.0, seed=seed)
        Record(t, u[0], simulate(Oscillator(), t, u)[0].detach()).to_csv(tmp_path / f"{name}.csv")
    (tmp_path / "config.yaml").write_text("physics: {class_path: two_outputs.TwoOutputs}\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr("sys.argv", ["torchpaml"])
    with pytest.raises(SystemExit) as stop:
        main(["diagnose", "--config", "config.yaml", "--data", "train.csv", "--validation", "validation.csv",
              "--out", "out"])
    err = capsys.readouterr().err.strip()
    assert stop.value.code == 2 and "\n" not in err
    assert err.startswith("torchpaml diagnose: error: record 'train' has 1 output channel(s), but TwoOutputs has 2 "
                          "(output_dim)")
