"""``torchpaml diagnose``: the command-line contract, a user-defined physics and effect from --config, and errors."""

import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from torchpaml.cli import main
from torchpaml import EFFECTS

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane

FIGURES = ("compare", "residual_analysis", "error_by_amplitude", "ranking", "ladder")
OUTPUTS_PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference" / "outputs.md"


def field_names(content, names=None) -> set[str]:
    """Every key of a JSON document, at any depth, except those of maps keyed by data (parameters, effects)."""
    names = set() if names is None else names
    if isinstance(content, dict):
        for key, value in content.items():
            names.add(key)
            if key not in ("parameters", "uncertainty", "skipped_candidates", "effect"):
                field_names(value, names)
    elif isinstance(content, list):
        for item in content:
            field_names(item, names)
    return names

USER_MODEL = '''
import torch
from torchpaml import SecondOrderPhysics, AbstractPhysics, PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics import AbstractEffect


class Spring(SecondOrderPhysics):
    """A user's mass-spring-damper: x'' = g u - c v - k x."""

    def __init__(self, c=1.0, k=3.0, g=1.0, learn=("c", "k", "g")):
        super().__init__()
        register_parameters(self, [PhysicalParameter("c", c, "1/s", Real()), PhysicalParameter("k", k, "1/s^2", Positive()),
                                   PhysicalParameter("g", g, "1/s^2", Real())], tuple(learn))

    def acceleration(self, t, x, v, u):
        return self.g * u - self.c * v - self.k * x


class CubicDamping(AbstractEffect):
    """A user's candidate: F = -c3 v^3."""

    name, equation = "cubic_damping", "- c3*v^3"

    def __init__(self, c3=0.0):
        super().__init__()
        register_parameters(self, [PhysicalParameter("c3", c3, "s/m^2", Real())], ("c3",))

    def force(self, physics, x, v, u):
        return -self.c3 * v**3


class Tank(AbstractPhysics):
    """First-order physics: effects for mechanical physics do not fit it."""

    state_names = ("level",)

    def __init__(self, a=1.0):
        super().__init__()
        register_parameters(self, [PhysicalParameter("a", a, "1/s", Positive())], ("a",))

    def derivative(self, t, x, u):
        return u - self.a * x

    def output(self, x, u):
        return x


class ScalarSpring(Spring):
    """A mistake: the acceleration summed to one number."""

    def acceleration(self, t, x, v, u):
        return (self.g * u - self.c * v - self.k * x).sum()


class RaisingSpring(Spring):
    """A mistake: a name that does not exist."""

    def acceleration(self, t, x, v, u):
        return self.g * u - self.damping * v


class NaNSpring(Spring):
    """A mistake: a division by the position, which starts at 0."""

    def acceleration(self, t, x, v, u):
        return self.g * u - self.k * x**2 / x
'''


def run(*args, cwd, env=None):
    return subprocess.run([sys.executable, "-m", "torchpaml", "diagnose", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=600, env=env)


def simulate_cli(cwd, name, signal, seed, effect="quadratic_damping=0.5"):
    done = subprocess.run(
        [sys.executable, "-m", "torchpaml", "simulate", "--physics", "oscillator", "--set", "zeta=0.2", "--set",
         "gain=4", "--effect", effect, "--signal", signal, "--amplitude", "1", "--duration", "30", "--dt", "0.05",
         "--noise", "0.02", "--seed", str(seed), "--out", name],
        capture_output=True, text=True, cwd=cwd, timeout=300)
    assert done.returncode == 0, done.stderr


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """Train (pseudorandom) and validation (multisine) CSVs with a hidden quadratic damping, written by the CLI."""
    folder = tmp_path_factory.mktemp("measured")
    simulate_cli(folder, "train.csv", "pseudorandom", 0)
    simulate_cli(folder, "val.csv", "multisine", 1)
    return folder


def test_the_contract_run_writes_json_figures_html_and_tensorboard(measured):
    done = run("--data", "train.csv", "--validation", "val.csv", "--physics", "oscillator", "--fix", "omega0=2.0",
               "--out", "out", "--discover", cwd=measured)
    assert done.returncode == 0, done.stderr
    out = measured / "out"
    report = json.loads((out / "diagnosis.json").read_text())
    assert {"baseline", "ranking", "ladder", "verdict"} <= set(report)
    assert {"nrmse_train", "nrmse_validation", "parameters"} <= set(report["baseline"])
    assert report["baseline"]["parameters"]["omega0"] == 2.0  # fixed
    assert sorted(e["effect"] for e in report["ranking"]) == sorted(EFFECTS)
    assert all({"effect", "score", "nrmse_validation", "parameters"} <= set(e) for e in report["ranking"])
    assert report["ranking"][0]["effect"] == "quadratic_damping"
    assert report["ranking"][0]["parameters"]["quadratic_damping.c2"] == pytest.approx(0.5, rel=0.1)
    ladder = report["ladder"]
    assert [step["model"] for step in ladder] == ["Oscillator", "Oscillator + quadratic_damping"]
    assert ladder[1]["nrmse_validation"] < ladder[0]["nrmse_validation"] / 2
    assert "quadratic_damping" in report["verdict"]
    first, last = report["hybrid"]  # the orthogonal residual does not hide the missing damping; on top of it, noise
    assert first["inadequate"] and "PHYSICS INADEQUATE" in first["message"], first
    assert not last["inadequate"] and last["message"].startswith("physics complete at this noise level"), last
    html = (out / "report.html").read_text()
    for name in FIGURES:
        assert (out / "figures" / f"{name}.png").stat().st_size > 1000
        assert f'src="figures/{name}.png"' in html
    events = EventAccumulator(str(out / "tensorboard"), size_guidance={"scalars": 0, "images": 0})
    events.Reload()
    series = [e.value for e in events.Scalars("ladder/nrmse_validation")]
    assert series == pytest.approx([step["nrmse_validation"] for step in ladder], rel=1e-6)
    assert {f"diagnose/{name}" for name in FIGURES} <= set(events.Tags()["images"])
    # --discover on the ladder's last rung, which lacks nothing (complete at the noise level): it says so and stops
    discovery = json.loads((out / "discovery.json").read_text())
    assert {"expression", "terms", "recommended", "nrmse_validation", "library_best", "searched"} <= set(discovery)
    assert set(discovery["nrmse_validation"]) == {"physics", "library_best", "neural", "discovered"}
    assert discovery["expression"] == "0" and discovery["terms"] == [] and not discovery["recommended"], discovery
    assert not discovery["searched"] and discovery["nrmse_validation"]["neural"] is None
    assert "is complete at this noise level" in discovery["reason"] and "--discover_always" in discovery["reason"]
    assert discovery["nrmse_validation"]["physics"] == pytest.approx(ladder[1]["nrmse_validation"], rel=1e-9)
    assert report["discovery"] == discovery and "Discovery: " in report["verdict"]
    assert not (out / "figures" / "discovery.png").exists() and 'src="figures/discovery.png"' not in html
    assert "Discovery" in html and not (out / "discovered_effect.yaml").exists()
    assert report["schema_version"] == discovery["schema_version"] == 1
    spans = re.findall(r"`([^`]+)`", OUTPUTS_PAGE.read_text())
    documented = {word for span in spans for word in re.findall(r"\w+", span)}
    assert sorted(field_names(report) - documented) == []  # every field of diagnosis.json and discovery.json
    assert events.Scalars("discovery/nrmse_validation/discovered")[0].value == pytest.approx(
        discovery["nrmse_validation"]["discovered"], rel=1e-6)


def spring_records(folder):
    """A user's Spring with a hidden cubic damping (c3 = 0.6): its module and train.csv / val.csv written into
    ``folder``; returns the environment that imports the module."""
    (folder / "user_model.py").write_text(USER_MODEL)
    env = {**os.environ, "PYTHONPATH": str(folder)}
    script = textwrap.dedent("""
        from user_model import Spring, CubicDamping
        from torchpaml._data import Simulated
        true = Spring(c=0.8, k=4.0, g=4.0, learn=()) + CubicDamping(0.6)
        for signal, seed, name in (("pseudorandom", 0, "train.csv"), ("multisine", 1, "val.csv")):
            Simulated(true, signal, 1.0, [seed], 30.0, 0.05, noise=0.02).experiments()[0].to_csv(name)
    """)
    subprocess.run([sys.executable, "-c", script], check=True, cwd=folder, env=env, timeout=300)
    return env


def test_user_physics_and_user_effect_from_a_config(tmp_path):
    """A user's Spring with data from a hidden user effect (cubic damping): ranked first against a library effect."""
    env = spring_records(tmp_path)
    (tmp_path / "config.yaml").write_text(textwrap.dedent("""
        data: train.csv
        validation: val.csv
        out: out
        physics:
          class_path: user_model.Spring
          init_args: {c: 0.5, k: 3.0, g: 2.0}
        effects: [quadratic_stiffness]
        candidates:
          - class_path: user_model.CubicDamping
    """))
    done = run("--config", "config.yaml", cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert report["ranking"][0]["effect"] == "cubic_damping"
    assert report["ranking"][0]["parameters"]["cubic_damping.c3"] == pytest.approx(0.6, rel=0.15)
    assert [step["model"] for step in report["ladder"]] == ["Spring", "Spring + cubic_damping"]


def test_discovery_alone_on_a_users_physics_from_a_config(tmp_path):
    """``effects: []`` and ``discover: true`` on a user's Spring with a hidden cubic damping, with a user term."""
    env = spring_records(tmp_path)
    (tmp_path / "config.yaml").write_text(textwrap.dedent("""
        data: train.csv
        validation: val.csv
        out: out
        physics: {class_path: user_model.Spring, init_args: {c: 0.5, k: 3.0, g: 2.0}}
        effects: []
        discover: true
        terms: ["x**2*sign(v)"]
    """))
    done = run("--config", "config.yaml", cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr
    discovery = json.loads((tmp_path / "out" / "discovery.json").read_text())
    assert discovery["recommended"] and discovery["library_best"] is None, discovery
    (term,) = discovery["terms"]
    assert term["term"] == "v**3" and term["equation"] == "acceleration", discovery
    assert term["coefficient"] == pytest.approx(-0.6, rel=0.1) and 0 < term["std"] < 0.1 * abs(term["coefficient"])
    assert "v**3" in (tmp_path / "out" / "discovered_effect.yaml").read_text()
    spans = re.findall(r"`([^`]+)`", OUTPUTS_PAGE.read_text())
    documented = {word for span in spans for word in re.findall(r"\w+", span)}
    assert sorted(field_names(discovery) - documented) == []


@pytest.mark.parametrize("args, config, message", [
    (["--physics", "spring"], None, "unknown physics 'spring'"),
    (["--effect", "cubic"], None, "unknown effect(s) ['cubic']"),
    (["--fix", "k9=1"], None, "unknown parameter(s) ['k9']"),
    (["--fix", "omega0"], None, "is not NAME=NUMBER"),
    (["--data", "bad.csv"], None, "missing column(s) ['y']"),
    (["--data", "absent.csv"], None, "absent.csv"),
    (["--effect", "cubic_stiffness"], "physics: {class_path: user_model.Tank}", "cubic_stiffness is a force"),
    ([], "physics: {class_path: user_model.Spring, init_args: {c: -4.0}}", "blew up"),
    (["--out", "train.csv"], None, "is an existing file"),
    (["--shortlist", "-1"], None, "--shortlist must be at least 1"),
    (["--hold", "xoh"], None, "hold"),
    (["--data", "short.csv"], None, "has 3 samples, too few"),
    ([], "physics: {class_path: user_model.ScalarSpring}",
     "ScalarSpring.acceleration returned shape (), expected (4,)"),
    ([], "physics: {class_path: user_model.RaisingSpring}", "RaisingSpring.acceleration raised AttributeError"),
    ([], "physics: {class_path: user_model.NaNSpring}", "NaNSpring.acceleration returned NaN or infinity at the "
                                                        "starting parameters {'c': 1.0, 'k': 3.0, 'g': 1.0}"),
    ([], "physics: {class_path: user_model.NoSuchSpring}", "config key 'physics': "),
    (["--discover", "--term", "w**2"], None, "term 'w**2' uses ['w'], which are not variables of this physics"),
    ([], "physics: {class_path: user_model.Spring, init_args: {kk: 1.0}}",
     "config key 'physics': Problem with given class_path 'user_model.Spring': Option 'kk' is not accepted"),
])
def test_bad_input_exits_2_with_a_message(measured, tmp_path, monkeypatch, capsys, args, config, message):
    """In-process (the console script's ``main``), so that eleven runs do not pay eleven interpreter start-ups."""
    (tmp_path / "user_model.py").write_text(USER_MODEL)
    (tmp_path / "bad.csv").write_text("t,u\n0,1\n0.1,2\n")
    (tmp_path / "short.csv").write_text("t,u,y\n0,1,0\n0.05,1,0.01\n0.1,1,0.02\n")
    for name in ("train.csv", "val.csv"):
        (tmp_path / name).write_text((measured / name).read_text())
    base = ["--data", "train.csv", "--validation", "val.csv", "--out", "out"]
    if config is not None:
        (tmp_path / "config.yaml").write_text(config + "\n")
        base = ["--config", "config.yaml", *base]
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "argv", ["torchpaml", "diagnose", *base, *args])
    with pytest.raises(SystemExit) as exit_:
        main()
    captured = capsys.readouterr()
    assert exit_.value.code == 2, captured.out + captured.err
    assert message in captured.err
    assert len(captured.err.strip().splitlines()) <= 3, captured.err


def test_verbose_prints_the_traceback_of_an_error_in_the_users_physics(measured, tmp_path, monkeypatch, capsys):
    (tmp_path / "user_model.py").write_text(USER_MODEL)
    (tmp_path / "config.yaml").write_text("physics: {class_path: user_model.RaisingSpring}\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "argv", ["torchpaml", "diagnose", "--config", "config.yaml", "--data",
                                      str(measured / "train.csv"), "--validation", str(measured / "val.csv"), "--out",
                                      "out", "--verbose"])
    with pytest.raises(SystemExit) as exit_:
        main()
    err = capsys.readouterr().err
    assert exit_.value.code == 2
    assert "Traceback" in err and "self.damping" in err and err.strip().endswith(
        "fix the method (--verbose prints the traceback)")


@pytest.mark.parametrize("quiet", [False, True])
def test_progress_lines_on_stderr_unless_quiet(measured, tmp_path, monkeypatch, capsys, quiet):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", ["torchpaml", "diagnose", "--data", str(measured / "train.csv"), "--validation",
                                      str(measured / "val.csv"), "--out", "out", "--effect", "quadratic_damping",
                                      *(["--quiet"] if quiet else [])])
    main()
    err = capsys.readouterr().err
    lines = re.findall(r"^torchpaml diagnose \[ *[0-9.]+ s\] (.*)$", err, flags=re.MULTILINE)
    if quiet:
        assert lines == [], err
    else:
        assert lines[0] == ("diagnosing Oscillator on 1 training and 1 validation record(s), 1200 samples; budget: "
                            "600 s for the whole diagnosis (budget=, --budget)")
        assert lines[1] == "fitting Oscillator on 600 samples"
        assert any(line.startswith("refitting Oscillator + quadratic_damping (at most ") for line in lines), lines
        assert lines[-1] == "fitting the Chebyshev residual on top"
