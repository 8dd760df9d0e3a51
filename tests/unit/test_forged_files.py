"""Model files forged as an attacker would (the digest recomputed): a term carrying Python, a class path naming a
module with import side effects, a string attribute and a hold carrying ``*/`` and a C constructor. Each is refused
in one line, by ``load_model`` and with exit 2 by every command that reads a model, and the marker file that the
payload would write never appears. The exporters' own guard keeps a comment closed whatever a physics' equation
says."""

import ast
import sys
from pathlib import Path

import pytest
import torch

from torchpaml import (RK4, ConfigurationError, CoulombFriction, DiscoveredForce, FittedModel, Oscillator, Record,
                       load_model, pseudorandom, save_model, time_grid)
from torchpaml._export.code import c_code, exported_step, python_code
from torchpaml._model.file import _checksum
from torchpaml._physics.terms import compile_term
from torchpaml.cli import main

H = 0.05


def _model() -> FittedModel:
    force = DiscoveredForce(terms=["v**3"], coefficients=[-0.5])
    return FittedModel(Oscillator(zeta=0.15) + CoulombFriction(0.2) + force, RK4(substeps=1), step=H,
                       noise=(0.01,))


def _forged(path: Path, change) -> Path:
    """The model file at ``path`` with ``change`` applied to its content and the digest recomputed: a forgery
    that the digest cannot catch."""
    stored = torch.load(path, weights_only=True)
    change(stored["content"])
    torch.save({"content": stored["content"], "sha256": _checksum(stored["content"])}, path)
    return path


def _discovered(physics: dict) -> dict:
    """The DiscoveredForce's spec inside a composed physics' spec."""
    found = []

    def walk(value):
        if isinstance(value, dict):
            if str(value.get("class_path", "")).endswith("DiscoveredForce"):
                found.append(value)
            for item in value.values():
                walk(item)
        elif isinstance(value, list):
            for item in value:
                walk(item)
    walk(physics)
    return found[0]


def _term(marker: Path):
    payload = f"__import__('os').system('touch {marker}') or x**3"
    return lambda content: _discovered(content["physics"])["kwargs"].__setitem__("terms", {"list": [payload]})


def _class_path(marker: Path):
    return lambda content: content["physics"].__setitem__("class_path", "evil_import.Device")


def _attribute(marker: Path):
    constructor = (f"*/ __attribute__((constructor)) static void own(void) {{ system(\"touch {marker}\"); }} /*")
    return lambda content: content["physics"]["attributes"][""].__setitem__("display", constructor)


def _hold(marker: Path):
    constructor = (f"foh */ __attribute__((constructor)) static void own(void) {{ system(\"touch {marker}\"); }} /*")
    return lambda content: content.__setitem__("hold", constructor)


FORGERIES = {
    "a term carrying Python": (_term, r"is not plain text|is not allowed in a term"),
    "a class path with import side effects": (_class_path, r"outside torchpaml.*--trust evil_import"),
    "a string attribute carrying C": (_attribute, r"is not plain text"),
    "a hold carrying C": (_hold, r"hold must be 'foh'"),
}


@pytest.fixture
def planted(tmp_path, monkeypatch):
    """A module on the path whose import writes a marker (what a forged class path would run), and the marker."""
    marker = tmp_path / "pwned"
    (tmp_path / "evil_import.py").write_text(f"from pathlib import Path\nPath({str(marker)!r}).touch()\n"
                                             "from torchpaml import Oscillator as Device\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "evil_import", raising=False)
    return marker


@pytest.mark.parametrize("forgery", list(FORGERIES))
def test_a_forged_file_is_refused_by_load_model_in_one_line_and_nothing_runs(forgery, planted, tmp_path):
    change, message = FORGERIES[forgery]
    path = _forged(save_model(_model(), tmp_path / "model.pt"), change(planted))
    with pytest.raises(ConfigurationError, match=message) as refused:
        load_model(path)
    assert "\n" not in str(refused.value)
    assert not planted.exists()


@pytest.mark.parametrize("command", ["simulate", "export", "track"])
@pytest.mark.parametrize("forgery", list(FORGERIES))
def test_every_command_that_reads_a_model_refuses_a_forged_file_with_exit_2(forgery, command, planted, tmp_path,
                                                                           capsys, monkeypatch):
    change, message = FORGERIES[forgery]
    path = _forged(save_model(_model(), tmp_path / "model.pt"), change(planted))
    t = time_grid(5.0, H)
    Record(t, pseudorandom(t, 1.0, seed=0)[0], torch.zeros(len(t), 1)).to_csv(tmp_path / "stream.csv")
    args = {"simulate": ["--data", "stream.csv", "--out", "out.csv"], "export": ["--code", "model.c"],
            "track": ["--data", "stream.csv", "--out", "track"]}[command]
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.argv", ["torchpaml"])
    with pytest.raises(SystemExit) as stop:
        main([command, "--model", str(path), *args])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and len(err.strip().splitlines()) == 1, err
    assert ("--trust" in err) == (forgery == "a class path with import side effects")
    assert not planted.exists() and not (tmp_path / "model.c").exists()


def test_a_trusted_package_loads_and_an_untrusted_one_is_never_imported(planted, tmp_path):
    """A class path outside torchpaml is imported only where the user trusts its package."""
    path = _forged(save_model(_model(), tmp_path / "model.pt"), _class_path(planted))
    with pytest.raises(ConfigurationError, match="outside torchpaml"):
        load_model(path, trust=("other_package",))
    assert not planted.exists()
    with pytest.raises(ConfigurationError, match="trust names packages"):
        load_model(path, trust=("evil_import; rm",))
    with pytest.raises(ConfigurationError, match=r"arguments do not build evil_import\.Device"):
        load_model(path, trust=("evil_import",))  # trusted: imported (its marker written), then the class checked
    assert planted.exists()


@pytest.mark.parametrize("text", ["__import__('os').system('true') or x**3", "x.__class__", "(lambda: x)()",
                                  "x[0]", "open(x)", "x if v else u", "x**y", "2**10**10", "'x'"])
def test_a_term_is_parsed_as_data_never_run(text):
    with pytest.raises(ConfigurationError, match=r"term .*(is not allowed in a term|exponent)"):
        compile_term(text, ("x", "v", "u"))


def test_a_term_the_library_writes_reads_back_the_same():
    for text in ["x**2*tanh(v/eps)", "sqrt(Abs(x))", "-0.5*v**3 + 2", "v**(3/2)", "sign(v)*exp(-x)", "1"]:
        canonical = compile_term(text, None).text
        assert compile_term(canonical, None).text == canonical


class Announced(Oscillator):
    """A user's physics whose equation carries text that would end a comment (built in Python, not read from a
    file: the exporters' guard is the last line of defence)."""

    def equation(self) -> str:
        return 'x */ int own = 1; /* """ ; import os'


def test_generated_code_keeps_a_hostile_equation_inside_its_comment_and_docstring():
    step = exported_step(FittedModel(Announced(), RK4(substeps=1), step=H))
    source = c_code(step)
    first = source.splitlines()[0]
    assert first.startswith("/*") and first.endswith("*/") and first.count("*/") == 1
    assert "int own" not in source.split("*/", 1)[1]
    module = ast.parse(python_code(step))
    assert ast.get_docstring(module).startswith("x * / int own = 1? / * ??? ? import os")
    assert all(not isinstance(node, ast.Import) or node.names[0].name == "math" for node in module.body)
