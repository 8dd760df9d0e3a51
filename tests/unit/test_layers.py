"""The layers import downwards only: the package-level import graph of torchpaml has no circle."""

import ast
from pathlib import Path

import torchpaml

ROOT = Path(torchpaml.__file__).parent


def _layer(module: str) -> str:
    """``torchpaml._simulate.solvers`` -> ``_simulate``; a top-level module is its own layer."""
    return module.split(".")[1]


def _imports(path: Path) -> set[str]:
    """The torchpaml modules ``path`` imports when it is imported: module level, outside ``if TYPE_CHECKING``."""
    found = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("torchpaml."):
            found.add(node.module)
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("torchpaml.")}
    return found


def _graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for path in ROOT.rglob("*.py"):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        if len(parts) < 2 or parts[1] in ("__init__", "__main__"):
            continue
        layer = parts[1]
        graph.setdefault(layer, set()).update(_layer(m) for m in _imports(path) if _layer(m) != layer)
    return graph


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


def test_the_layers_import_each_other_without_a_circle():
    graph = _graph()
    assert {"_physics", "_simulate", "_data", "_fit", "_diagnostics", "_render"} <= set(graph)
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


def test_the_simulator_sees_tensors_and_physics_only():
    assert not {"_data", "_fit", "_diagnostics", "_render", "_training", "cli"} & _graph()["_simulate"]


def test_no_function_is_longer_than_80_lines():
    long = [f"{path.relative_to(ROOT.parent)}:{node.name} ({node.end_lineno - node.lineno + 1} lines)"
            for path in ROOT.rglob("*.py") for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.end_lineno - node.lineno >= 80]
    assert long == []
