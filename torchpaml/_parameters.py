r"""Named physical parameters with units, constraints, and a fixed/learnable switch.

A physical parameter $\theta$ is stored as an unconstrained tensor $\rho$ and exposed through a
constraint map $\theta = c(\rho)$ registered with :mod:`torch.nn.utils.parametrize`, so optimisers
work on $\rho \in \mathbb{R}$ while users read and assign $\theta$ in physical units:

* :class:`Real`: $\theta = \rho$;
* :class:`Positive`: $\theta = e^{\rho}$, $\rho = \log\theta$;
* :class:`Interval`: $\theta = a + (b - a)\,\sigma(\rho)$, $\rho = \operatorname{logit}((\theta - a)/(b - a))$.

A fixed parameter keeps ``requires_grad=False`` on $\rho$.

A saturating map (:class:`Positive`, :class:`Interval`) reaches its limit only as $|\rho| \to \infty$, and a fit
that the data drive there can leave $\rho$ anywhere out there ($-6.6\cdot 10^4$ and $-3.5\cdot 10^4$ for the same
parameter of the cascaded tanks, one with records perturbed by 1e-12): a number that means nothing, and whose size
sets the next fit's first trust region. Each fit therefore starts with $|\rho|$ at most :data:`RAW_LIMIT`
(:func:`raw_limits`), where the map is within $e^{-40} = 4\cdot 10^{-18}$ of its limit.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace

import torch

from torchpaml._errors import ConfigurationError
from torch import nn
from torch.nn.utils import parametrize

__all__ = [
    "Interval",
    "PhysicalParameter",
    "Positive",
    "RAW_LIMIT",
    "Real",
    "constrain",
    "copied_with_own_parametrizations",
    "describe_parameters",
    "format_table",
    "raw_limits",
    "register_parameters",
    "unphysical_values",
    "with_uncertainty",
]


#: The largest $|\rho|$ a fit starts from on a saturating constraint (module docstring).
RAW_LIMIT = 40.0


class Real(nn.Module):
    """Identity constraint: any real value."""

    raw_limit = math.inf

    def forward(self, raw: torch.Tensor) -> torch.Tensor:
        return raw

    def right_inverse(self, value: torch.Tensor) -> torch.Tensor:
        return value

    def check(self, name: str, value: float) -> None:
        if not math.isfinite(value):
            raise ConfigurationError(f"parameter {name!r} must be finite, got {value}")

    def __repr__(self) -> str:
        return "real"


class Positive(nn.Module):
    r"""$\theta = e^{\rho} > 0$."""

    raw_limit = RAW_LIMIT

    def forward(self, raw: torch.Tensor) -> torch.Tensor:
        return torch.exp(raw)

    def right_inverse(self, value: torch.Tensor) -> torch.Tensor:
        return torch.log(value)

    def check(self, name: str, value: float) -> None:
        if not (math.isfinite(value) and value > 0):
            raise ConfigurationError(f"parameter {name!r} must be positive and finite, got {value}; pass a value > 0")

    def __repr__(self) -> str:
        return "> 0"


class Interval(nn.Module):
    r"""$\theta = a + (b - a)\,\sigma(\rho) \in (a, b)$."""

    raw_limit = RAW_LIMIT

    def __init__(self, lower: float, upper: float):
        super().__init__()
        if not lower < upper:
            raise ConfigurationError(f"Interval needs lower < upper, got ({lower}, {upper})")
        self.lower, self.upper = float(lower), float(upper)

    def forward(self, raw: torch.Tensor) -> torch.Tensor:
        return self.lower + (self.upper - self.lower) * torch.sigmoid(raw)

    def right_inverse(self, value: torch.Tensor) -> torch.Tensor:
        return torch.logit((value - self.lower) / (self.upper - self.lower))

    def check(self, name: str, value: float) -> None:
        if not self.lower < value < self.upper:
            raise ConfigurationError(
                f"parameter {name!r} must lie in the open interval ({self.lower}, {self.upper}), got {value}"
            )

    def __repr__(self) -> str:
        return f"in ({self.lower:g}, {self.upper:g})"


@dataclass(frozen=True)
class PhysicalParameter:
    """Declaration of one physical parameter: its initial value, unit, constraint and meaning.

    ``constraint`` is enforced (the parametrisation cannot leave it); ``physical``, the range where the
    value means what the physics says (a share in [0, 1], a dissipative coefficient >= 0), is only
    checked: a fit that ends outside it is flagged by :func:`unphysical_values`, never silently kept.
    """

    name: str
    value: float
    unit: str = "-"
    constraint: nn.Module | None = None
    meaning: str = ""
    physical: tuple[float, float] | None = None


def raw_limits(module: nn.Module, names: list[str]) -> list[float]:
    """Each named parameter's largest raw magnitude a fit starts from: :data:`RAW_LIMIT` on a saturating constraint,
    unlimited on :class:`Real` and on a user's own constraint map without a ``raw_limit``."""
    limits = []
    for name in names:
        owner, leaf = module._owner(name)
        limits.append(float(getattr(getattr(owner.parametrizations, leaf)[0], "raw_limit", math.inf)))
    return limits


def register_parameters(module: nn.Module, declarations: list[PhysicalParameter], learn: tuple[str, ...]) -> None:
    """Create the constrained parameters ``declarations`` on ``module``; only names in ``learn`` get gradients.

    Raises ``ValueError`` for a name in ``learn`` that is not declared, or a value the constraint rejects.
    """
    names = [d.name for d in declarations]
    unknown = sorted(set(learn) - set(names))
    if unknown:
        raise ConfigurationError(f"cannot learn unknown parameter(s) {unknown}; {type(module).__name__} has {names}")
    declarations = [d if d.constraint is not None else replace(d, constraint=Real()) for d in declarations]
    module._physical = {d.name: d for d in declarations}
    for d in declarations:
        constraint = d.constraint
        constraint.check(d.name, float(d.value))
        module.register_parameter(d.name, nn.Parameter(torch.tensor(float(d.value), dtype=torch.float64)))
        parametrize.register_parametrization(module, d.name, constraint, unsafe=True)
        getattr(module.parametrizations, d.name).original.requires_grad_(d.name in learn)


def constrain(module: nn.Module, name: str, constraint: nn.Module) -> None:
    """Give the declared parameter ``name`` of ``module`` the ``constraint`` map from now on, keeping its value and its
    learnable flag."""
    learn = getattr(module.parametrizations, name).original.requires_grad
    parametrize.remove_parametrizations(module, name, leave_parametrized=True)
    parametrize.register_parametrization(module, name, constraint, unsafe=True)
    getattr(module.parametrizations, name).original.requires_grad_(learn)
    module._physical[name] = replace(module._physical[name], constraint=constraint)


def copied_with_own_parametrizations(module: nn.Module, memo: dict) -> nn.Module:
    """A deep copy of ``module`` whose parametrized parameters are read through its own properties.

    ``torch.nn.utils.parametrize`` gives a parametrized module a class of its own, whose properties read the
    parameters through a closure over *that* module; a plain deep copy shares the class, so inside
    ``parametrize.cached()`` (the simulators' context) every copy reads the cache entry of the original. Two
    copies of one effect in one model (``CoulombFriction().on("v1")`` and ``.on("v2")``) then saw each other's
    values. The copy here gets a class and properties of its own."""
    replica = module.__new__(type(module))
    memo[id(module)] = replica
    replica.__dict__ = copy.deepcopy(module.__dict__, memo)
    if parametrize.is_parametrized(module):
        replica.__class__ = type(module).__bases__[0]
        parametrize._inject_new_class(replica)
        for name in replica.parametrizations:
            parametrize._inject_property(replica, name)
    return replica


def declared(module: nn.Module) -> dict:
    """``{name: PhysicalParameter}`` declared on ``module`` itself (:func:`register_parameters`); empty for a module
    that declares none."""
    return getattr(module, "_physical", {})


def describe_parameters(module: nn.Module, prefix: str = "") -> list[dict]:
    """Rows ``{name, value, unit, constraint, learnable, meaning}`` (and ``physical``, where declared) for every
    physical parameter below ``module``; :func:`with_uncertainty` adds a fit's."""
    rows = []
    for path, sub in module.named_modules():
        for name, decl in declared(sub).items():
            raw = getattr(sub.parametrizations, name).original
            row = {
                "name": prefix + (f"{path}.{name}" if path else name),
                "value": float(getattr(sub, name).detach()),
                "unit": decl.unit,
                "constraint": repr(getattr(sub.parametrizations, name)[0]),
                "learnable": bool(raw.requires_grad),
                "meaning": decl.meaning,
            }
            if decl.physical is not None:
                row["physical"] = decl.physical
            rows.append(row)
    return rows


def unphysical_values(rows: list[dict]) -> list[str]:
    """Messages for the :func:`describe_parameters` rows that lie outside their declared ``physical`` range.

    A row with a 95 % interval (after a fit) is flagged only when the whole interval is outside: a
    value at the edge of its range (a pendulum's share of sin x fitted at 1.001 +- 0.003) is physical
    within its uncertainty.
    """
    messages = []
    for r in rows:
        if "physical" not in r:
            continue
        lo, hi = r["physical"]
        low, high = r.get("interval", (r["value"], r["value"]))
        if high < lo or low > hi:
            messages.append(f"{r['name']} = {r['value']:.4g} is outside its physical range [{lo:g}, {hi:g}]"
                            + ("" if "interval" not in r else f" (95 % interval [{low:.4g}, {high:.4g}])"))
    return messages


def with_uncertainty(rows: list[dict], std: dict[str, float], interval: dict[str, tuple[float, float]]) -> list[dict]:
    """``rows`` (of :func:`describe_parameters`) with a fit's standard errors ``std`` and 95 % intervals ``interval``
    (``PhysicsEstimate.uncertainty``'s) on the parameters it fitted."""
    return [{**r, "std": std[r["name"]], "interval": interval[r["name"]]} if r["name"] in std else r for r in rows]


def format_table(rows: list[dict]) -> str:
    """A plain-text table of :func:`describe_parameters` rows, with ± std and the 95 % interval after a fit."""
    fitted = any("std" in r for r in rows)
    spread = f" {'± std':>10} {'95 % interval':<25}" if fitted else ""
    header = f"{'parameter':<16} {'value':>12}{spread} {'unit':<8} {'constraint':<16} {'status':<8} meaning"
    lines = [header, "-" * len(header)]
    for r in rows:
        status = "learned" if r["learnable"] else "fixed"
        if fitted:
            lo, hi = r.get("interval", (None, None))
            spread = (f" {r['std']:>10.3g} {f'[{lo:.4g}, {hi:.4g}]':<25}" if "std" in r else f" {'':>10} {'':<25}")
        lines.append(f"{r['name']:<16} {r['value']:>12.6g}{spread} {r['unit']:<8} {r['constraint']:<16} {status:<8} "
                     f"{r['meaning']}")
    return "\n".join(lines)
