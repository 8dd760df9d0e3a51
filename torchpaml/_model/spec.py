"""A module or a solver as plain data (class path, arguments, attributes, tensors), and built again from it.

:func:`module_spec` describes a physics, an effect or a residual (any :class:`~torchpaml._arguments.Rebuildable`):
its ``class_path`` (``module.Class``), the arguments it was built with (a module among them described the same way),
the plain attributes of it and of each of its submodules (an effect placed by ``on("v2")`` keeps its new name), its
parameters' constraints and learnable flags, and its ``state_dict`` (the raw parameters, bit for bit).
:func:`built_module` checks the spec first (every class path names torchpaml or a package the caller trusts,
checked before anything is imported; every string is plain text, :func:`~torchpaml._text.check_plain_text`; every
parameter name a dotted identifier), then imports the class by its path, calls it with the arguments, sets the
attributes, the constraints and the flags, and loads the state. A solver (a frozen dataclass) is its class path and fields
(:func:`solver_spec`, :func:`built_solver`). Nothing here unpickles: the data are numbers, strings, lists, dicts
and tensors, which ``torch.load(weights_only=True)`` reads.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
from collections.abc import Sequence
from typing import Any

import torch
from torch import nn

from torchpaml._arguments import Rebuildable, built_with
from torchpaml._errors import ConfigurationError, TorchpamlError
from torchpaml._parameters import Interval, constrain, declared
from torchpaml._simulate.solvers import Solver
from torchpaml._text import check_plain_text

__all__ = ["built_module", "built_solver", "check_classes", "check_trust", "class_named", "module_spec", "solver_spec", "trusted"]

_DOTTED = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")
#: Plain values a model file keeps as they are.
PLAIN = (bool, int, float, str, type(None))


def _path(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


def trusted(path: str, trust: tuple[str, ...]) -> bool:
    """Whether the class path ``path`` lies in torchpaml or in a package of ``trust`` (``"mypkg"`` allows
    ``mypkg.physics.Device``), judged on the text alone."""
    return any(path.startswith(f"{package}.") for package in ("torchpaml", *trust))


def check_trust(trust: Sequence[str]) -> tuple[str, ...]:
    """``trust`` as a tuple of dotted package names; a name that is not one is refused in one line."""
    trust = (trust,) if isinstance(trust, str) else tuple(trust)
    bad = [t for t in trust if not (isinstance(t, str) and _DOTTED.fullmatch(t))]
    if bad:
        raise ConfigurationError(f"trust names packages (trust=('mypkg',), --trust mypkg), got {bad}")
    return trust


def class_named(path: str, kind: type, trust: tuple[str, ...] = ()) -> type:
    """The class ``module.Class`` at ``path``, which must derive from ``kind``. A path outside torchpaml and the
    ``trust``ed packages is refused before its module is imported (importing runs the module's code); a missing
    class is refused in one line."""
    if not (isinstance(path, str) and _DOTTED.fullmatch(path)):
        raise ConfigurationError(f"the model file names the class {str(path)[:60]!r}, which is not a class path "
                                 "(module.Class); the file was not written by torchpaml.save_model or was changed")
    if not trusted(path, trust):
        package = path.split(".")[0]
        raise ConfigurationError(f"the model file names the class {path}, outside torchpaml; loading it would import "
                                 f"and run the package {package!r}: if you trust it, allow it with "
                                 f"load_model(path, trust=({package!r},)) or --trust {package}")
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


def check_classes(value: Any, trust: tuple[str, ...]) -> None:
    """Every ``class_path`` anywhere in ``value`` (a model file's content) is a class path in torchpaml or a trusted
    package (:func:`class_named`'s refusals), checked on the text before any module is imported."""
    if isinstance(value, dict):
        if "class_path" in value:
            path = value["class_path"]
            if not (isinstance(path, str) and _DOTTED.fullmatch(path)) or not trusted(path, trust):
                class_named(path, object, trust)  # raises its one-line refusal; nothing trusted is imported
        for item in value.values():
            check_classes(item, trust)
    elif isinstance(value, (list, tuple)):
        for item in value:
            check_classes(item, trust)


def _check_strings(value: Any, where: str) -> None:
    """Every string in ``value`` (plain data: dicts, lists, strings, numbers, tensors) is plain text."""
    if isinstance(value, str):
        check_plain_text(value, where)
    elif isinstance(value, dict):
        for key, item in value.items():
            _check_strings(key, f"{where}, a key")
            _check_strings(item, f"{where}[{key!r}]" if isinstance(key, str) and len(key) < 40 else where)
    elif isinstance(value, (list, tuple)):
        for item in value:
            _check_strings(item, where)


def _check_spec(spec: dict) -> None:
    """The spec's strings are plain text and its parameter names dotted identifiers (module docstring)."""
    owner = spec["class_path"]
    for part in ("args", "kwargs", "attributes"):
        _check_strings(spec[part], f"{owner}'s {part}")
    for name in (*spec["constraints"], *spec["state"]):
        if not (isinstance(name, str) and _DOTTED.fullmatch(name)):
            raise ConfigurationError(f"{owner} names a parameter {str(name)[:60]!r}, which is not a dotted identifier; "
                                     "the file was not written by torchpaml.save_model or was changed")


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


def _built_value(value: Any, trust: tuple[str, ...]) -> Any:
    if not isinstance(value, dict):
        return value
    (kind, content), = value.items()
    if kind == "module":
        return built_module(content, trust)
    if kind == "tensor":
        return content
    if kind in ("list", "tuple"):
        items = [_built_value(v, trust) for v in content]
        return items if kind == "list" else tuple(items)
    return {k: _built_value(v, trust) for k, v in content.items()}


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


def built_module(spec: dict, trust: tuple[str, ...] = ()) -> nn.Module:
    """The module that :func:`module_spec` described, its parameters bit for bit; classes outside torchpaml load
    only from the packages of ``trust`` (module docstring)."""
    cls = class_named(spec["class_path"], Rebuildable, trust)
    _check_spec(spec)
    args = [_built_value(v, trust) for v in spec["args"]]
    kwargs = {k: _built_value(v, trust) for k, v in spec["kwargs"].items()}
    try:
        module = cls(*args, **kwargs)
    except TorchpamlError:
        raise
    except (TypeError, ValueError) as error:  # arguments that do not fit the class: a changed file, not a bug
        raise ConfigurationError(f"the model file's arguments do not build {spec['class_path']} ("
                                 f"{str(error).splitlines()[0] if str(error) else type(error).__name__}); the file "
                                 "was not written by torchpaml.save_model or was changed") from None
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


def built_solver(spec: dict, trust: tuple[str, ...] = ()) -> Solver:
    """The solver :func:`solver_spec` described (its class by the same permission as :func:`built_module`'s)."""
    cls = class_named(spec["class_path"], Solver, trust)
    _check_strings(spec["fields"], f"{spec['class_path']}'s fields")
    fields = {k: built_solver(v["solver"], trust) if isinstance(v, dict) and "solver" in v else v
              for k, v in spec["fields"].items()}
    return cls(**fields)
