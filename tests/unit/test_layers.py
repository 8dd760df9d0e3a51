"""The layers import downwards only: every import of torchpaml's modules, nested and ``TYPE_CHECKING`` ones
included, forms no circle, between modules or between layers."""

import ast
from pathlib import Path

import torchpaml

ROOT = Path(torchpaml.__file__).parent
#: The layers from the bottom up: a layer imports only layers before it (the top-level helpers are their own; the
#: public named modules, last, only gather names).
ORDER = ["_errors", "_text", "_arguments", "_grid", "_signals", "_parameters", "_budget", "_symbolic", "_simulate", "_physics", "_metrics",
         "_data", "_residual", "_fit", "_certificates", "_model", "_export", "_track", "_diagnostics", "_render", "_leaderboard", "_paper", "_training",
         "cli", "analysis", "engine", "figures", "report", "leaderboard"]


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module(path): path for path in ROOT.rglob("*.py")}


def _imports(path: Path) -> set[str]:
    """Every torchpaml module ``path`` imports, anywhere in it (module level, in functions, under ``if``)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("torchpaml"):
            found |= {f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in MODULES else node.module
                      for a in node.names}
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("torchpaml")}
    return found & set(MODULES)


def _layer(module: str) -> str:
    """``torchpaml._simulate.solvers`` -> ``_simulate``; ``torchpaml`` itself is the top."""
    return module.split(".")[1] if "." in module else "torchpaml"


def _graph(packages: bool) -> dict[str, set[str]]:
    """Module -> the modules it imports; a package's ``__init__`` (which re-exports) only with ``packages``."""
    skip = {m for m, path in MODULES.items() if path.name == "__init__.py" and not packages}
    return {m: _imports(path) - skip - {m} for m, path in MODULES.items() if m not in skip}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        state[node] = 2
        path.pop()
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_the_modules_import_each_other_without_a_circle():
    cycle = _cycle(_graph(packages=False))
    assert cycle is None, " -> ".join(cycle)


def test_every_layer_imports_only_the_layers_below_it():
    assert {_layer(m) for m in MODULES} - {"torchpaml", "__main__"} <= set(ORDER), "a new layer needs its place"
    upward = sorted(f"{m} imports {i}" for m, imported in _graph(packages=True).items() for i in imported
                    if _layer(m) in ORDER and _layer(i) in ORDER and ORDER.index(_layer(i)) > ORDER.index(_layer(m)))
    assert upward == []


def test_the_layer_test_sees_nested_and_type_checking_imports(tmp_path):
    source = tmp_path / "probe.py"
    source.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from torchpaml._fit import fit_physics\n"
                      "def f():\n    from torchpaml._simulate.solvers import RK4\n")
    assert _imports(source) == {"torchpaml._fit", "torchpaml._simulate.solvers"}


def test_the_simulator_sees_tensors_only():
    below = set(ORDER[: ORDER.index("_simulate")])
    assert {_layer(i) for m, imported in _graph(packages=True).items() if _layer(m) == "_simulate"
            for i in imported} - {"_simulate"} <= below


def test_no_function_is_longer_than_80_lines():
    long = [f"{path.relative_to(ROOT.parent)}:{node.name} ({node.end_lineno - node.lineno + 1} lines)"
            for path in ROOT.rglob("*.py") for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.end_lineno - node.lineno >= 80]
    assert long == []
