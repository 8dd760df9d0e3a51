"""A module or a solver as plain data (class path, arguments, attributes, tensors), and built again from it.

:func:`module_spec` describes a physics, an effect or a residual (any :class:`~torchpaml._arguments.Rebuildable`):
its ``class_path`` (``module.Class``), the arguments it was built with (a module among them described the same way),
the plain attributes of it and of each of its submodules (an effect placed by ``on("v2")`` keeps its new name), its
parameters' constraints and learnable flags, and its ``state_dict`` (the raw parameters, bit for bit).
:func:`built_module` imports the class by its path, calls it with the arguments, sets the attributes, the
constraints and the flags, and loads the state. A solver (a frozen dataclass) is its class path and fields
(:func:`solver_spec`, :func:`built_solver`). Nothing here unpickles: the data are numbers, strings, lists, dicts
and tensors, which ``torch.load(weights_only=True)`` reads.
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any

import torch
from torch import nn

from torchpaml._arguments import Rebuildable, built_with
from torchpaml._errors import ConfigurationError
from torchpaml._parameters import Interval, constrain, declared
from torchpaml._simulate.solvers import Solver

__all__ = ["built_module", "built_solver", "class_named", "module_spec", "solver_spec"]

#: Plain values a model file keeps as they are.
PLAIN = (bool, int, float, str, type(None))


def _path(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


def class_named(path: str, kind: type) -> type:
    """The class ``module.Class`` at ``path``, which must derive from ``kind``; a missing one is refused in one line."""
    module, _, name = path.rpartition(".")
    try:
        cls = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError):
        raise ConfigurationError(f"the model file names class {path}, which cannot be imported here; install or put on "
                                 "PYTHONPATH the package that defines it (as a config's class_path needs)") from None
    if not (isinstance(cls, type) and issubclass(cls, kind)):
        raise ConfigurationError(f"the model file names {path}, which is not a {kind.__name__}; the file was not "
                                 "written by torchpaml or was changed")
    return cls


def _value(value: Any, owner: str, name: str) -> Any:
    """An argument as plain data: a module as its spec, a tensor as it is, containers element by element."""
    if isinstance(value, Rebuildable):
        return {"module": module_spec(value)}
    if isinstance(value, torch.Tensor):
        return {"tensor": value.detach().clone()}
    if isinstance(value, PLAIN):
        return value
    if isinstance(value, (list, tuple)):
        return {"list" if isinstance(value, list) else "tuple": [_value(v, owner, name) for v in value]}
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return {"dict": {k: _value(v, owner, name) for k, v in value.items()}}
    raise ConfigurationError(f"cannot save {owner}: its argument {name!r} is a {type(value).__name__}; a model file "
                             "keeps numbers, strings, lists, dicts, tensors and torchpaml modules as arguments")


def _built_value(value: Any) -> Any:
    if not isinstance(value, dict):
        return value
    (kind, content), = value.items()
    if kind == "module":
        return built_module(content)
    if kind == "tensor":
        return content
    if kind in ("list", "tuple"):
        items = [_built_value(v) for v in content]
        return items if kind == "list" else tuple(items)
    return {k: _built_value(v) for k, v in content.items()}


def _attributes(module: nn.Module) -> dict[str, dict[str, Any]]:
    """The plain attributes (numbers, strings, tuples of them) of ``module`` and each submodule, by path."""
    found = {}
    for path, sub in module.named_modules():
        plain = {k: v for k, v in vars(sub).items() if not k.startswith("_") and (
            isinstance(v, PLAIN) or isinstance(v, tuple) and all(isinstance(e, PLAIN) for e in v))}
        found[path] = {k: list(v) if isinstance(v, tuple) else v for k, v in plain.items()}
    return found


def _constraints(module: nn.Module) -> dict[str, dict[str, Any]]:
    """Each physical parameter's interval bound (``[lower, upper]``, or ``None``) and learnable flag, by name."""
    rows = {}
    for path, sub in module.named_modules():
        for name in declared(sub):
            parametrization = getattr(sub.parametrizations, name)
            bound = parametrization[0]
            rows[f"{path}.{name}" if path else name] = {
                "interval": [bound.lower, bound.upper] if isinstance(bound, Interval) else None,
                "learnable": bool(parametrization.original.requires_grad)}
    return rows


def module_spec(module: Rebuildable) -> dict:
    """``module`` as plain data (module docstring)."""
    cls, args, kwargs = built_with(module)
    owner = cls.__name__
    return {"class_path": _path(cls),
            "args": [_value(v, owner, f"#{i}") for i, v in enumerate(args)],
            "kwargs": {k: _value(v, owner, k) for k, v in kwargs.items()},
            "attributes": _attributes(module), "constraints": _constraints(module),
            "state": {k: v.detach().clone() for k, v in module.state_dict().items()}}


def built_module(spec: dict) -> nn.Module:
    """The module that :func:`module_spec` described, its parameters bit for bit."""
    cls = class_named(spec["class_path"], Rebuildable)
    module = cls(*[_built_value(v) for v in spec["args"]], **{k: _built_value(v) for k, v in spec["kwargs"].items()})
    modules = dict(module.named_modules())
    for path, attributes in spec["attributes"].items():
        for name, value in attributes.items():
            setattr(modules[path], name, tuple(value) if isinstance(value, list) else value)
    for name, row in spec["constraints"].items():
        path, _, leaf = name.rpartition(".")
        owner = modules[path]
        if row["interval"] is not None:
            constrain(owner, leaf, Interval(*row["interval"]))
        getattr(owner.parametrizations, leaf).original.requires_grad_(row["learnable"])
    module.load_state_dict(spec["state"])
    return module


def solver_spec(solver: Solver) -> dict:
    """A solver (a frozen dataclass) as its class path and fields."""
    if not dataclasses.is_dataclass(solver):
        raise ConfigurationError(f"cannot save the solver {type(solver).__name__}: a model file keeps solvers that are "
                                 "dataclasses (every torchpaml solver is one)")
    fields = {f.name: getattr(solver, f.name) for f in dataclasses.fields(solver) if f.init}
    return {"class_path": _path(type(solver)),
            "fields": {k: {"solver": solver_spec(v)} if isinstance(v, Solver) else v for k, v in fields.items()}}


def built_solver(spec: dict) -> Solver:
    """The solver :func:`solver_spec` described."""
    cls = class_named(spec["class_path"], Solver)
    fields = {k: built_solver(v["solver"]) if isinstance(v, dict) and "solver" in v else v
              for k, v in spec["fields"].items()}
    return cls(**fields)
