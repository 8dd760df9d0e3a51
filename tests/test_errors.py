"""Bad input gets a clear error naming the problem and the fix; each one is pinned here."""

import re
import subprocess
import sys

import pytest
import torch

from torchpaml import Dopri5, Exact, TRBDF2
from torchpaml import (
    AbstractPhysics,
    ChebyshevHammerstein,
    DataError,
    DomainError,
    Record,
    Oscillator,
    PhysicalParameter,
    Real,
    register_parameters,
    simulate,
    SimulationError,
    sine,
    time_grid,
)


def _write(tmp_path, text):
    path = tmp_path / "data.csv"
    path.write_text(text)
    return path


def test_missing_column(tmp_path):
    with pytest.raises(DataError, match=r"missing column\(s\) \['y'\].*expected 't,u,y'"):
        Record.from_csv(_write(tmp_path, "t,u\n0,1\n1,2\n"))


def test_nan_value(tmp_path):
    with pytest.raises(DataError, match="column 'y' has 1 NaN/inf value.*row 1.*drop or interpolate"):
        Record.from_csv(_write(tmp_path, "t,u,y\n0,1,1\n1,2,nan\n2,3,3\n"))


def test_time_not_strictly_increasing(tmp_path):
    with pytest.raises(DataError, match=r"strictly increasing.*t\[2\].*remove duplicate"):
        Record.from_csv(_write(tmp_path, "t,u,y\n0,1,1\n1,2,2\n1,3,3\n"))


def test_non_uniform_sampling_where_uniform_is_required(tmp_path):
    experiment = Record.from_csv(_write(tmp_path, "t,u,y\n0,1,1\n1,2,2\n3,3,3\n"))
    with pytest.raises(DataError, match="uniform sampling is required.*resample"):
        experiment.dt
    with pytest.raises(DataError, match="uniform sampling is required"):
        simulate(Oscillator(), experiment.t, experiment.u[None], solver=Exact())


def test_length_mismatch():
    with pytest.raises(DataError, match="length mismatch, t has 3 samples, u 3, y 2"):
        Record(torch.arange(3.0), torch.zeros(3), torch.zeros(2))


def test_empty_file(tmp_path):
    with pytest.raises(DataError, match="is empty"):
        Record.from_csv(_write(tmp_path, ""))
    with pytest.raises(DataError, match="no data rows"):
        Record.from_csv(_write(tmp_path, "t,u,y\n"))


def test_input_beyond_the_chebyshev_domain_raises():
    t = time_grid(2.0, 0.01)
    with pytest.raises(DomainError, match=r"\|u\| = 5.*alpha = 4.*alpha >= 5"):
        ChebyshevHammerstein(4.0)(t, sine(t, 5.0, 1.0))


def test_unstable_parameters_are_rejected():
    with pytest.raises(ValueError, match="must be positive"):
        Oscillator(zeta=-0.2)


class _Runaway(AbstractPhysics):
    state_names = ("x",)

    def __init__(self):
        super().__init__()
        register_parameters(self, [PhysicalParameter("rate", 3.0, "1/s", Real())], ())

    def derivative(self, t, x, u):
        return self.rate * x**3 + u

    def output(self, x, u):
        return x


@pytest.mark.parametrize("solver", [None, Dopri5(max_num_steps=2000), TRBDF2(substeps=1)])
def test_ode_that_blows_up_raises_simulation_error(solver):
    t = time_grid(5.0, 0.01)
    with pytest.raises(SimulationError, match="blows up|blew up|did not converge"):
        simulate(_Runaway(), t, sine(t, 3.0, 1.0), solver=solver)


def test_cli_exits_non_zero_with_a_message(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "torchpaml", "paper", "--seeds", "0", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
    )
    assert result.returncode != 0 and "--seeds must be at least 1" in result.stderr


@pytest.mark.parametrize("case, message", [
    ("no_units_folder", "is not a folder; give a folder with one sub-folder per unit"),
    ("empty_units_folder", "has no unit folders; put one folder per unit in it"),
    ("unknown_physics", "unknown physics 'spring'"),
    ("no_ray", "install the extra: pip install 'torchpaml\\[fleet\\]'"),
])
def test_fleet_refuses_bad_input_before_starting_ray(tmp_path, monkeypatch, capsys, case, message):
    from torchpaml.cli import main

    units = tmp_path / "units"
    if case != "no_units_folder":
        units.mkdir()
    if case in ("unknown_physics", "no_ray"):
        (units / "unit0").mkdir()
    monkeypatch.setitem(sys.modules, "ray", None)  # Ray cannot be imported: nothing here may start it
    monkeypatch.setattr(sys, "argv", ["torchpaml"])
    physics = "spring" if case == "unknown_physics" else "oscillator"
    with pytest.raises(SystemExit) as exit_:
        main(["fleet", "--units", str(units), "--physics", physics, "--out", str(tmp_path / "out"), "--quiet"])
    assert exit_.value.code == 2
    assert re.search(f"torchpaml fleet: error: .*{message}", capsys.readouterr().err)


@pytest.mark.parametrize("option, value, message", [
    ("--refit_budget", "0", "--refit_budget must be positive and finite, got 0"),
    ("--budget", "-5", "--budget is the seconds the whole diagnosis may take, > 0"),
])
def test_diagnose_refuses_a_budget_that_allows_nothing_before_any_fit(tmp_path, monkeypatch, capsys, option, value,
                                                                       message):
    from torchpaml.cli import main

    record = _write(tmp_path, "t,u,y\n" + "".join(f"{i},{i % 3},{i % 2}\n" for i in range(50)))
    monkeypatch.setattr(sys, "argv", ["torchpaml"])
    with pytest.raises(SystemExit) as exit_:
        main(["diagnose", "--data", str(record), "--validation", str(record), "--out", str(tmp_path / "out"),
              option, value, "--quiet"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err
