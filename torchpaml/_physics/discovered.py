r"""A force, rate or output term found by discovery, as a first-class effect: $R_e = g \sum_{i:\,e_i = e} c_i\,\theta_i(z)$.

Each term $\theta_i$ (a sympy string over the physics' variables $z$, :mod:`~torchpaml._physics.terms`)
adds, times its coefficient $c_i$ and the gain $g$, to the rate of its equation $e_i$: the
acceleration of second-order physics (variables ``x``, ``v``, ``u``), or a named state's equation of
any other physics (variables its ``state_names`` and ``u``); or, with the equation ``"output"``, to the output of a
physics with one output, $y = h(x, u) + g \sum_{i:\,e_i = \text{output}} c_i\,\theta_i(x, u)$: a closed form of the
output map.

Parameters: ``gain`` $g$ (the strength: at 0 the effect is off; fixed at 1 unless asked), one
coefficient per term, ``c_<term>`` (``c_v3`` for ``v**3``, ``c_u_x2`` for ``u*x**2``,
``c_tanh_v_eps`` for ``tanh(v/eps)``; ``c_<equation>_<term>`` on physics that is not second order),
and one positive width per width symbol that the terms use (``eps`` in ``tanh(v/eps)``, m/s: the data
sets the shape of the sign). :meth:`DiscoveredForce.expression` prints the force with the fitted numbers.

In a config (``candidates:`` of ``torchpaml diagnose --config``, or anywhere jsonargparse builds an
effect)::

    class_path: torchpaml.DiscoveredForce      # or by its name alone: DiscoveredForce
    init_args: {terms: ["v**3"], coefficients: [-0.49]}
"""

from __future__ import annotations

import math

import re
from collections.abc import Mapping, Sequence

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._errors import ConfigurationError
from torchpaml._parameters import PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics.effects import AbstractEffect
from torchpaml._physics.terms import compile_term, input_values, input_variables, state_columns, variables_of

__all__ = ["OUTPUT", "DiscoveredForce"]

#: The equation of a term that adds to the output (:class:`DiscoveredForce`).
OUTPUT = "output"

def _slug(text: str) -> str:
    """A parameter-name fragment of a term: ``"x**2*tanh(v/eps)"`` -> ``"x2_tanh_v_eps"``."""
    return re.sub(r"_+", "_", re.sub(r"\W", "_", text.replace("**", ""))).strip("_") or "1"


class DiscoveredForce(AbstractEffect):
    r"""$g\sum_i c_i\,\theta_i$ on each term's equation (module docstring).

    Args:
        terms: the terms $\theta_i$, sympy strings, e.g. ``["v**3", "x**2*tanh(v/eps)"]``.
        coefficients: $c_i$, one per term (default 0).
        equations: the equation of each term (default ``"acceleration"``: second-order physics);
            a state name of other physics; ``"output"``: the term adds to the output.
        widths: the starting value of each width symbol the terms use, ``{"eps": 0.05}`` (default 0.01).
        gain: $g$, the strength.
        learn: learnable parameters; default the coefficients and the widths.
        eps: the width ``eps`` (shorthand for ``widths={"eps": ...}``).
    """

    name = "discovered"

    def __init__(self, terms: Sequence[str] = (), coefficients: Sequence[float] | None = None,
                 equations: Sequence[str] | None = None, widths: Mapping[str, float] | None = None,
                 gain: float = 1.0, *, learn: Sequence[str] | None = None, eps: float | None = None):
        super().__init__()
        terms = list(terms)
        coefficients = [0.0] * len(terms) if coefficients is None else [float(c) for c in coefficients]
        equations = ["acceleration"] * len(terms) if equations is None else list(equations)
        if not len(coefficients) == len(equations) == len(terms):
            raise ConfigurationError(f"DiscoveredForce needs one coefficient and one equation per term: {len(terms)} terms, "
                             f"{len(coefficients)} coefficients, {len(equations)} equations")
        self.equations = equations
        self.reads_input = self.reads_state = OUTPUT in equations  # an output term reads the states and inputs
        mechanical = set(equations) <= {"acceleration", OUTPUT}  # its parameters are named by their terms alone
        compiled = [compile_term(t, ("x", "v", "u") if "acceleration" in equations else None) for t in terms]
        self.terms = [c.text for c in compiled]
        self._compiled = compiled
        pairs = list(zip(self.equations, self.terms, strict=True))
        if len(set(pairs)) != len(pairs):
            raise ConfigurationError(f"DiscoveredForce terms must be distinct within an equation, got {pairs}")
        self.parameter_names = [f"c_{_slug(t)}" if mechanical else f"c_{e}_{_slug(t)}" for e, t in pairs]
        starts = {**({"eps": eps} if eps is not None else {}), **dict(widths or {})}
        self.width_names = sorted({w for c in compiled for w in c.widths})
        parameters = [PhysicalParameter("gain", gain, "-", Real(), "strength of the discovered terms")]
        parameters += [PhysicalParameter(n, c, "-", Real(), f"coefficient of {t} in the {e} equation")
                       for n, t, c, e in zip(self.parameter_names, self.terms, coefficients, equations, strict=True)]
        parameters += [PhysicalParameter(w, float(starts.get(w, 0.01)), "-", Positive(), "width of a smoothed sign")
                       for w in self.width_names]
        default = [*self.parameter_names, *self.width_names]
        register_parameters(self, parameters, default if learn is None else learn)
        written = {equation: [f"{n}*{t}" for n, t, e in zip(self.parameter_names, self.terms, equations, strict=True)
                              if (e == OUTPUT) == (equation == OUTPUT)] for equation in ("rate", OUTPUT)}
        self.equation = " ".join([*(["+ " + (" + ".join(written["rate"]) or "0")] if written["rate"] or not
                                    written[OUTPUT] else []),
                                  *(["y -> y + " + " + ".join(written[OUTPUT])] if written[OUTPUT] else [])])

    def applies_to(self, physics: AbstractPhysics) -> str | None:
        variables, equations = variables_of(physics)
        wrong = sorted({e for e in self.equations if e not in equations and e != OUTPUT})
        if OUTPUT in self.equations and physics.output_dim != 1:
            return f"its output terms add to a single output; {physics.display_name} has {physics.output_dim}"
        if wrong:
            return (f"its terms add to the equation(s) {wrong}, but {physics.display_name}'s equations are "
                    f"{list(equations)}")
        unknown = sorted({n for c in self._compiled for n in re.findall(r"[A-Za-z_]\w*", c.text)}
                         - {*variables, *self.width_names, "Abs", "sign", "sqrt", "tanh", "exp", "sin", "cos"})
        if unknown:
            return f"its terms use {unknown}, which are not variables of {physics.display_name} ({list(variables)})"
        return None

    def rate(self, physics: AbstractPhysics, x, u):
        values = {name: x[..., i] for name, i in state_columns(physics).items()}
        values.update(input_values(physics, u))
        equations = variables_of(physics)[1]
        values.update({w: getattr(self, w) for w in self.width_names})
        totals: dict[str, torch.Tensor] = {}
        for name, equation, term in zip(self.parameter_names, self.equations, self._compiled, strict=True):
            if equation == OUTPUT:
                continue
            value = getattr(self, name) * term.evaluate(values)
            totals[equation] = totals.get(equation, 0.0) + value
        if "acceleration" in equations:
            totals = {physics.state_names[1]: totals["acceleration"]} if totals else {}
        return self.on_state(physics, x, {k: self.gain * v for k, v in totals.items()})

    def output_map(self, y, z=None, u=None, x=None, physics=None):
        """``y`` plus the output terms, read in the layout of ``y`` (..., n_y, batch) from the base ``physics``' states
        ``x`` (..., n, batch) and inputs ``u`` (..., n_u, batch)."""
        if OUTPUT not in self.equations:
            return y
        values = {name: x[..., i, :] for name, i in state_columns(physics).items()}
        values.update({name: u[..., i, :] for i, name in enumerate(input_variables(physics))})
        values.update({w: getattr(self, w) for w in self.width_names})
        total = torch.zeros_like(y[..., 0, :])
        for name, equation, term in zip(self.parameter_names, self.equations, self._compiled, strict=True):
            if equation == OUTPUT:
                total = total + getattr(self, name) * term.evaluate(values)
        return y + (self.gain * total)[..., None, :]

    def values(self) -> dict[str, float]:
        """Every parameter's value, ``{name: float}``."""
        return {name: float(getattr(self, name).detach()) for name in self._physical}

    def terms_and_coefficients(self) -> list[tuple[str, float, str]]:
        """``[(term, g c_i, equation)]`` with the fitted widths written in: the terms in numbers."""
        values = self.values()
        rows = []
        for name, term, equation in zip(self.parameter_names, self.terms, self.equations, strict=True):
            for width in sorted(self.width_names, key=len, reverse=True):
                term = re.sub(rf"\b{width}\b", f"{values[width]:.4g}", term)
            rows.append((term, values["gain"] * values[name], equation))
        return rows

    def coefficient_errors(self, uncertainty: dict[str, float]) -> list[float]:
        """The standard error of each term's coefficient $g c_i$ (:meth:`terms_and_coefficients`) from a fit's
        standard errors of $c_i$ (``uncertainty``, keyed by the parameters' names in the model, e.g.
        ``discovered.c_v3``), $|g|$ times it (the gain fixed); ``inf`` where the fit does not determine one."""
        gain = abs(self.values()["gain"])
        return [gain * uncertainty.get(f"{self.name}.{name}", math.inf) for name in self.parameter_names]

    def expression(self) -> str | dict[str, str]:
        """The terms as one sympy-style string, e.g. ``"-0.4894*v**3"`` (``"0"`` without terms); on several
        equations, ``{equation: string}``."""
        by_equation: dict[str, list[str]] = {}
        for term, c, equation in self.terms_and_coefficients():
            by_equation.setdefault(equation, []).append(f"{c:.4g}*{term}" if term != "1" else f"{c:.4g}")
        joined = {e: " + ".join(parts).replace("+ -", "- ") for e, parts in by_equation.items()}
        if len(joined) > 1:
            return joined
        return next(iter(joined.values()), "0")

    def to_config(self) -> dict:
        """``{"class_path", "init_args"}``: rebuilds this effect (fitted values) in a config."""
        values = self.values()
        init = {"terms": list(self.terms), "coefficients": [values[n] for n in self.parameter_names],
                "equations": list(self.equations), "gain": values["gain"]}
        if self.width_names:
            init["widths"] = {w: values[w] for w in self.width_names}
        return {"class_path": "torchpaml.DiscoveredForce", "init_args": init}
