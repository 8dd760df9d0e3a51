"""Physics and effects by name, for the command line and configs: ``build_model("oscillator", {...}, {...})``."""

from __future__ import annotations

from torchpaml._errors import ConfigurationError
from torchpaml._physics.effects import EFFECTS
from torchpaml._physics.oscillator import Oscillator
from torchpaml._physics.pendulum import Pendulum

__all__ = ["PHYSICS", "build_model", "parse_assignments"]

#: Library physics by command-line name.
PHYSICS = {"oscillator": Oscillator, "pendulum": Pendulum}


def parse_assignments(items: list[str] | None, what: str) -> dict[str, float]:
    """``["a=1", "b=2.5"]`` -> ``{"a": 1.0, "b": 2.5}``; a malformed item raises ``ValueError`` naming it."""
    values = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            if not sep or not name:
                raise ValueError
            values[name.strip()] = float(value)
        except ValueError:
            raise ConfigurationError(f"{what} {item!r} is not NAME=NUMBER (e.g. zeta=0.3)") from None
    return values


def build_model(physics: str, parameters: dict[str, float] | None = None, effects: dict[str, float] | None = None):
    """Library ``physics`` (by name) with ``parameters`` assigned, plus ``effects`` {name: strength}.

    An effect's strength is its first parameter (``cubic_stiffness=2`` sets k3 = 2); its other
    parameters can be set in ``parameters`` as ``effect.parameter`` (``coulomb_friction.eps``).
    """
    if physics not in PHYSICS:
        raise ConfigurationError(f"unknown physics {physics!r}; choose one of {sorted(PHYSICS)}")
    model = PHYSICS[physics](learn=())
    for name, strength in (effects or {}).items():
        if name not in EFFECTS:
            raise ConfigurationError(f"unknown effect {name!r}; choose from {sorted(EFFECTS)}")
        effect = EFFECTS[name]()
        model = model + effect
        model.assign(**{f"{name}.{effect.strength}": strength})
    known = set(model.physical_parameters())
    unknown = sorted(set(parameters or {}) - known)
    if unknown:
        raise ConfigurationError(f"unknown parameter(s) {unknown} for {model.display_name}; it has {sorted(known)}")
    return model.assign(**(parameters or {}))
