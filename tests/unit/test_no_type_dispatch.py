"""Behaviour lives in methods, not in type tests: no code branches on a concrete solver's class (a check that an
argument is a ``Solver`` at all, for a clear error, is not a branch), and no attribute is probed
for with ``hasattr`` or a defaulted ``getattr`` outside the two places that must (Lightning's logger, whose
experiment may be any object, and the parameters' registry)."""

import ast
from pathlib import Path

import torchpaml

ROOT = Path(torchpaml.__file__).parent
#: The concrete solvers: a type test on any of them is a branch a new solver cannot join.
SOLVER_TYPES = {"Auto", "Dopri5", "Exact", "FixedStep", "RK4", "TRBDF2"}
#: Where probing an attribute is the interface: Lightning's logger, and the registry of physical parameters.
PROBING_ALLOWED = {"torchpaml/_training/system.py", "torchpaml/_training/residual_fit.py", "torchpaml/_parameters.py"}


def _calls(name: str):
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == name:
                yield path.relative_to(ROOT.parent).as_posix(), node


def _names(node: ast.expr) -> set[str]:
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name)} | {
        n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)}


def test_no_code_tests_the_type_of_a_solver():
    found = [f"{path}:{node.lineno}" for path, node in _calls("isinstance") if _names(node.args[1]) & SOLVER_TYPES]
    assert found == []


def test_no_attribute_is_probed_outside_the_logger_and_the_registry():
    probes = [f"{path}:{node.lineno}" for path, node in _calls("hasattr") if path not in PROBING_ALLOWED]
    defaulted = [f"{path}:{node.lineno}" for path, node in _calls("getattr")
                 if len(node.args) == 3 and path not in PROBING_ALLOWED]
    assert probes + defaulted == []


def test_the_checks_see_what_they_look_for(tmp_path):
    source = "isinstance(solver, (RK4, Exact))\nhasattr(x, 'a')\ngetattr(x, 'a', None)\n"
    tree = ast.parse(source)
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)]
    assert _names(calls[0].args[1]) & SOLVER_TYPES == {"RK4", "Exact"}
    assert [c.func.id for c in calls] == ["isinstance", "hasattr", "getattr"] and len(calls[2].args) == 3
