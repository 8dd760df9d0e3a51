r"""A force found by discovery, as a first-class effect: $F = g \sum_i c_i\,\theta_i(x, v, u)$.

Each term $\theta_i$ is a product of the factors ``x``, ``v``, ``u``, ``Abs(v)`` and ``tanh(v/eps)``
(a smoothed sign of the velocity), each with an optional power ``**k``, written in that order and
joined by ``*`` (sympy's spelling): ``"v**3"``, ``"x**2*u"``, ``"v*Abs(v)"``, ``"x*tanh(v/eps)"``;
``"1"`` is the constant. :func:`candidate_terms` lists the library that discovery regresses on:

* the monomials of x, v and u of degree 0 to 3 (20 terms);
* $v|v|$ and $\tanh(v/\varepsilon)$, and their products with x, v and u (8 terms).

Parameters: ``gain`` $g$ (the strength: at 0 the force is off; fixed at 1 unless asked), one
coefficient ``c_<term>`` per term (``c_v3`` for ``v**3``, ``c_x2_u`` for ``x**2*u``, ``c_v_absv``
for ``v*Abs(v)``, ``c_tanhv`` for ``tanh(v/eps)``) and, where a term has the smoothed sign, its
width ``eps`` $\varepsilon$ (m/s, positive; learnable: the data sets the shape of the sign).

In a config (``candidates:`` of ``torchpaml diagnose --config``, or anywhere jsonargparse builds an
effect)::

    class_path: torchpaml.DiscoveredForce      # or by its name alone: DiscoveredForce
    init_args: {terms: ["v**3"], coefficients: [-0.49]}
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Sequence

import torch

from torchpaml._parameters import PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics.effects import AbstractEffect

__all__ = ["DiscoveredForce", "candidate_terms", "evaluate_term"]

_FACTOR = re.compile(r"(x|v|u|Abs\(v\)|tanh\(v/eps\))(?:\*\*([23]))?")
_ORDER = ("x", "v", "u", "Abs(v)", "tanh(v/eps)")
_SLUG = {"x": "x", "v": "v", "u": "u", "Abs(v)": "absv", "tanh(v/eps)": "tanhv"}


def _factors(term: str) -> list[tuple[str, int]]:
    """``"x**2*v"`` -> ``[("x", 2), ("v", 1)]``; ``"1"`` -> ``[]``; ``ValueError`` naming the grammar otherwise."""
    if term == "1":
        return []
    factors, position = [], 0
    while True:
        match = _FACTOR.match(term, position)
        if match is None:
            break
        factors.append((match.group(1), int(match.group(2) or 1)))
        position = match.end()
        if position == len(term):
            return factors
        if term[position] != "*":
            break
        position += 1
    raise ValueError(f"term {term!r} is not a product of x, v, u, Abs(v), tanh(v/eps) with optional powers **2, **3 "
                     "joined by '*' (e.g. 'x**2*v', 'v*Abs(v)', '1')")


def evaluate_term(term: str, x: torch.Tensor, v: torch.Tensor, u: torch.Tensor, eps) -> torch.Tensor:
    """The term's value at x, v, u (same shape); ``eps`` is the width of ``tanh(v/eps)``."""
    values = {"x": lambda: x, "v": lambda: v, "u": lambda: u, "Abs(v)": v.abs, "tanh(v/eps)": lambda: torch.tanh(v / eps)}
    result = torch.ones_like(x)
    for factor, power in _factors(term):
        result = result * values[factor]() ** power
    return result


def candidate_terms() -> list[str]:
    """The discovery library (module docstring), in a fixed order: 28 terms."""
    monomials = ["1"]
    for degree in (1, 2, 3):
        for combo in itertools.combinations_with_replacement(("x", "v", "u"), degree):
            monomials.append("*".join(f"{n}**{combo.count(n)}" if combo.count(n) > 1 else n
                                      for n in ("x", "v", "u") if n in combo))
    shaped = ["v*Abs(v)", "tanh(v/eps)"]
    products = ["x*v*Abs(v)", "v**2*Abs(v)", "v*u*Abs(v)", "x*tanh(v/eps)", "v*tanh(v/eps)", "u*tanh(v/eps)"]
    return monomials + shaped + products


def _slug(term: str) -> str:
    return "_".join(f"{_SLUG[f]}{p if p > 1 else ''}" for f, p in _factors(term)) or "1"


class DiscoveredForce(AbstractEffect):
    r"""$F = g\sum_i c_i\,\theta_i(x, v, u)$ (module docstring); a force on second-order physics.

    Args:
        terms: the terms $\theta_i$, e.g. ``["v**3", "x**2*u"]``.
        coefficients: $c_i$, one per term (default 0).
        eps: width of ``tanh(v/eps)`` (registered only when a term uses it).
        gain: $g$, the strength.
        learn: learnable parameters; default the coefficients and ``eps``.
    """

    name = "discovered"

    def __init__(self, terms: Sequence[str] = (), coefficients: Sequence[float] | None = None, eps: float = 0.01,
                 gain: float = 1.0, *, learn: Sequence[str] | None = None):
        super().__init__()
        terms = list(terms)
        coefficients = [0.0] * len(terms) if coefficients is None else [float(c) for c in coefficients]
        if len(coefficients) != len(terms):
            raise ValueError(f"DiscoveredForce needs one coefficient per term: {len(terms)} terms, "
                             f"{len(coefficients)} coefficients")
        if len(set(terms)) != len(terms):
            raise ValueError(f"DiscoveredForce terms must be distinct, got {terms}")
        order = {f: i for i, f in enumerate(_ORDER)}
        for term in terms:
            factors = _factors(term)
            if [order[f] for f, _ in factors] != sorted({order[f] for f, _ in factors}):
                raise ValueError(f"term {term!r}: write each factor once, in the order x, v, u, Abs(v), tanh(v/eps)")
        self.terms = terms
        self.parameter_names = [f"c_{_slug(t)}" for t in terms]
        parameters = [PhysicalParameter("gain", gain, "-", Real(), "strength of the discovered force")]
        parameters += [PhysicalParameter(n, c, "-", Real(), f"coefficient of {t}")
                       for n, t, c in zip(self.parameter_names, terms, coefficients, strict=True)]
        self.uses_sign = any("tanh" in t for t in terms)
        if self.uses_sign:
            parameters.append(PhysicalParameter("eps", eps, "m/s", Positive(), "smoothing velocity of tanh(v/eps)"))
        default = [*self.parameter_names, *(["eps"] if self.uses_sign else [])]
        register_parameters(self, parameters, default if learn is None else learn)
        self.equation = "+ " + (" + ".join(f"{n}*{t}" for n, t in zip(self.parameter_names, terms, strict=True)) or "0")

    def force(self, physics, x, v, u):
        eps = self.eps if self.uses_sign else None
        total = torch.zeros_like(x)
        for name, term in zip(self.parameter_names, self.terms, strict=True):
            total = total + getattr(self, name) * evaluate_term(term, x, v, u, eps)
        return self.gain * total

    def terms_and_coefficients(self) -> list[tuple[str, float]]:
        """``[(term, g c_i)]`` with the fitted width written into ``tanh(v/...)``: the force in numbers."""
        values = self.values()
        eps = f"{values['eps']:.4g}" if self.uses_sign else "eps"
        return [(t.replace("eps", eps), values["gain"] * values[n])
                for n, t in zip(self.parameter_names, self.terms, strict=True)]

    def values(self) -> dict[str, float]:
        """Every parameter's value, ``{name: float}``."""
        return {name: float(getattr(self, name).detach()) for name in self._physical}

    def expression(self) -> str:
        """The force as one sympy-style string over x, v, u, e.g. ``"-0.4894*v**3"``; ``"0"`` without terms."""
        parts = [f"{c:.4g}*{t}" if t != "1" else f"{c:.4g}" for t, c in self.terms_and_coefficients()]
        return " + ".join(parts).replace("+ -", "- ") or "0"

    def to_config(self) -> dict:
        """``{"class_path", "init_args"}``: rebuilds this force (fitted values) in a config."""
        values = self.values()
        init = {"terms": list(self.terms), "coefficients": [values[n] for n in self.parameter_names],
                "gain": values["gain"]}
        if self.uses_sign:
            init["eps"] = values["eps"]
        return {"class_path": "torchpaml.DiscoveredForce", "init_args": init}
