"""The model file (``model.pt``, ``hybrid.pt``): a :class:`~torchpaml.FittedModel` written and read without pickling
code.

:func:`save_model` writes, with ``torch.save``, a dict of plain data: the physics and the residual as
:func:`~torchpaml._model.spec.module_spec` describes them (class path, arguments, attributes, constraints, raw
parameters), the solver's fields, the channels' names, the records' hold, sampling interval and residual RMS, the
initial-state policy, the parameters' uncertainty, the library's version and a SHA-256 digest of all of it.
:func:`load_model` reads it with ``torch.load(weights_only=True)`` (tensors and plain containers only: a file that
carries code is refused by torch itself), checks the digest and the version, then checks what the file names
before anything is built: every class lies in torchpaml or in a package the caller trusts (``trust=("mypkg",)``,
``--trust mypkg``; judged on the class path's text, so an untrusted module is never imported), every string is
plain text (:func:`~torchpaml._text.check_plain_text`: nothing that could end a comment in the generated C or
Python), the hold is one of the library's, the channels' names are identifiers. Then it imports each class by its
path and builds the model again; its parameters are the saved ones bit for bit. Each refusal is one line: a file
from a newer torchpaml, a class outside the trusted packages or one that cannot be imported, text that is not plain,
a file changed after it was written.

The SHA-256 digest has no key: it catches a file damaged or edited by hand, not a forger, who recomputes it. What
keeps a forged file harmless is the checks above: a model file is data, and loading it runs no code of its own.
"""

from __future__ import annotations

import hashlib
import json
from importlib.metadata import PackageNotFoundError, version
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch

from torchpaml._errors import ConfigurationError
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._fit.initial_state import policy_named
from torchpaml._fit.uncertainty import Uncertainty
from torchpaml._grid import check_hold
from torchpaml._model.spec import built_module, built_solver, check_classes, check_trust, module_spec, solver_spec
from torchpaml._physics.base import AbstractPhysics
from torchpaml._residual.base import AbstractResidual

__all__ = ["FORMAT", "library_version", "load_model", "save_model"]

#: The file's format: what a key means. A reader refuses a file of a later format.
FORMAT = 1


def library_version() -> str:
    """torchpaml's installed version (``0+unknown`` when it runs from a source tree that is not installed)."""
    try:
        return version("torchpaml")
    except PackageNotFoundError:
        return "0+unknown"


def _release(text: str) -> tuple[int, ...]:
    """``"0.1.0"`` -> ``(0, 1, 0)``: the leading numbers of a version."""
    numbers = []
    for part in text.split("+")[0].split("."):
        if not part.isdigit():
            break
        numbers.append(int(part))
    return tuple(numbers)


def _digest(value: Any, sha: "hashlib._Hash") -> None:
    """Feed ``value`` (plain data and tensors) into ``sha`` in a canonical order."""
    if isinstance(value, dict):
        for key in sorted(value):
            sha.update(json.dumps(key).encode())
            _digest(value[key], sha)
    elif isinstance(value, (list, tuple)):
        sha.update(f"[{len(value)}".encode())
        for item in value:
            _digest(item, sha)
    elif isinstance(value, torch.Tensor):
        sha.update(f"{value.dtype}{tuple(value.shape)}".encode())
        sha.update(value.detach().contiguous().cpu().numpy().tobytes())
    else:
        sha.update(json.dumps(value).encode())


def _checksum(content: dict) -> str:
    sha = hashlib.sha256()
    _digest(content, sha)
    return sha.hexdigest()


def _uncertainty(value: Uncertainty | None) -> dict | None:
    if value is None:
        return None
    return {"std": dict(value.std), "interval": {k: list(v) for k, v in value.interval.items()},
            "correlation": value.correlation.detach().clone(), "collinearity": value.collinearity,
            "warning": value.warning}


def _built_uncertainty(value: dict | None) -> Uncertainty | None:
    if value is None:
        return None
    return Uncertainty(value["std"], {k: tuple(v) for k, v in value["interval"].items()}, value["correlation"],
                       value["collinearity"], value["warning"])


def save_model(model: FittedModel, path: str | Path) -> Path:
    """Write ``model`` to ``path`` (module docstring); returns the path.

    Raises :class:`~torchpaml.ConfigurationError` naming the part that a model file cannot keep (an argument of a
    user's class that is not a number, string, list, dict, tensor or torchpaml module)."""
    content = {
        "format": FORMAT, "torchpaml": library_version(),
        "physics": module_spec(model.physics), "solver": solver_spec(model.solver),
        "residual": None if model.residual is None else module_spec(model.residual),
        "inputs": list(model.inputs), "outputs": list(model.outputs), "hold": model.hold,
        "initial_state": model.initial_state.name, "uncertainty": _uncertainty(model.uncertainty),
        "step": model.step, "noise": list(model.noise),
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"content": content, "sha256": _checksum(content)}, path)
    return path


def _read(path: Path) -> dict:
    if not path.is_file():
        raise ConfigurationError(f"no model file at {path}; torchpaml diagnose writes one as model.pt in its --out "
                                 "folder")
    try:
        stored = torch.load(path, weights_only=True)
    except Exception as error:  # noqa: BLE001 - torch reports a refused or damaged file in several exception types
        first = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise ConfigurationError(f"{path} is not a torchpaml model file, or it carries code that loading refuses to "
                                 f"run ({first})") from None
    if not (isinstance(stored, dict) and set(stored) == {"content", "sha256"}):
        raise ConfigurationError(f"{path} is not a torchpaml model file (torchpaml.save_model writes them)")
    return stored


def _check_names(content: dict) -> None:
    """The hold is one of the library's and every channel name an identifier (module docstring)."""
    check_hold(content["hold"])
    for what in ("inputs", "outputs"):
        bad = [n for n in content[what] if not (isinstance(n, str) and n.isidentifier())]
        if bad:
            raise ConfigurationError(f"the model file names its {what} {bad}, which are not identifiers (letters, "
                                     "digits, _); the file was not written by torchpaml.save_model or was changed")


def load_model(path: str | Path, trust: Sequence[str] = ()) -> FittedModel:
    """The :class:`~torchpaml.FittedModel` saved at ``path`` (module docstring), its parameters bit for bit.

    ``trust``: the packages whose classes the file may name besides torchpaml's (a user's own physics, e.g.
    ``("mypkg",)``); a class elsewhere is refused before its module is imported.

    Raises :class:`~torchpaml.ConfigurationError` in one line for a file that is not a model file, one changed after
    it was written, one from a newer torchpaml or of a later format, one that names a class outside the trusted
    packages or one that cannot be imported, or one whose text is not plain."""
    path, trust = Path(path), check_trust(trust)
    stored = _read(path)
    content = stored["content"]
    if _checksum(content) != stored["sha256"]:
        raise ConfigurationError(f"{path} was changed after it was written (its SHA-256 digest does not match); "
                                 "write it again with torchpaml diagnose or torchpaml.save_model")
    written, here = content["torchpaml"], library_version()
    if content["format"] > FORMAT or _release(written) > _release(here):
        raise ConfigurationError(f"{path} was written by torchpaml {written} (file format {content['format']}); this "
                                 f"is torchpaml {here} (format {FORMAT}): upgrade torchpaml to load it")
    check_classes(content, trust)
    _check_names(content)
    physics = built_module(content["physics"], trust)
    residual = None if content["residual"] is None else built_module(content["residual"], trust)
    if not isinstance(physics, AbstractPhysics) or not (residual is None or isinstance(residual, AbstractResidual)):
        raise ConfigurationError(f"{path} does not hold a physics (and a residual); it was not written by "
                                 "torchpaml.save_model")
    return FittedModel(physics, built_solver(content["solver"], trust), residual, tuple(content["inputs"]),
                       tuple(content["outputs"]), content["hold"], policy_named(content["initial_state"]),
                       _built_uncertainty(content["uncertainty"]), content.get("step"),
                       tuple(content.get("noise", ())))
