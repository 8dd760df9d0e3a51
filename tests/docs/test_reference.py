"""The reference pages and the README stay true to the code: every public name, every option, the front page's contract."""

from __future__ import annotations

import re
from pathlib import Path

import torchpaml
import torchpaml.leaderboard  # a named module that `import torchpaml` does not load
from torchpaml.cli.commands import parser
from torchpaml.cli.diagnose import diagnose_command
from torchpaml.cli.fleet import FLEET_ARGUMENTS

ROOT = Path(__file__).resolve().parents[2]
API = (ROOT / "docs" / "reference" / "api.md").read_text()
CLI = (ROOT / "docs" / "reference" / "cli.md").read_text()


def test_every_public_name_is_in_the_api_reference():
    """The top level's names (the Lightning systems and the library's effects documented where they are defined,
    whose docs the top level re-exports), then each named module's, under its name."""
    private = r"_training|_physics\.effects|_physics\.memory_effects|_physics\.signal_effects"
    documented = set(re.findall(rf"^::: torchpaml\.(?:(?:{private})\.)?(\w+)$", API, re.M))
    assert sorted(set(torchpaml.__all__) - documented) == []
    assert sorted(documented - set(torchpaml.__all__)) == []  # nothing documented that is not exported
    for module in (torchpaml.analysis, torchpaml.engine, torchpaml.figures, torchpaml.report, torchpaml.leaderboard):
        named = set(re.findall(rf"^::: {module.__name__}\.(\w+)$", API, re.M))
        assert named == set(module.__all__), module.__name__


def test_the_top_level_is_a_surface_to_hold_in_the_head_and_old_names_still_work():
    import warnings

    assert len(torchpaml.__all__) < 120 and not any(n.endswith("_figure") for n in torchpaml.__all__)  # 136 before
    assert set(torchpaml.EFFECT_CLASSES) <= set(torchpaml.__all__)  # the library's effects, derived from EFFECTS
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert torchpaml.overlay_figure is torchpaml.figures.overlay_figure
    assert "torchpaml.figures.overlay_figure" in str(caught[0].message) and caught[0].category is DeprecationWarning


def test_every_option_of_simulate_and_paper_is_in_the_cli_reference():
    commands = parser()._subparsers._group_actions[0].choices
    options = {o for command in commands.values() for a in command._actions for o in a.option_strings
               if o.startswith("--") and o != "--help"}
    assert options >= {"--physics", "--signal", "--alpha", "--seeds"}  # the parser was read
    assert sorted(o for o in options if f"`{o}" not in CLI) == []


def test_every_option_of_diagnose_is_in_the_cli_reference():
    names = [n for n in diagnose_command.__code__.co_varnames[: diagnose_command.__code__.co_argcount]]
    spelled = {"effects": "--effect"}  # repeated on the command line as --effect NAME
    assert len(names) >= 14
    assert sorted(n for n in names if f"`{spelled.get(n, '--' + n)}" not in CLI) == []


def test_the_readme_is_a_front_page_with_the_two_setup_commands():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    assert "make demo" in readme and "make test" in readme


def test_every_option_of_fleet_is_in_the_cli_reference():
    fleet = CLI[CLI.index("## `torchpaml fleet`"):CLI.index("## `torchpaml simulate`")]
    assert sorted(a for a in FLEET_ARGUMENTS if f"`--{a}`" not in fleet) == []
