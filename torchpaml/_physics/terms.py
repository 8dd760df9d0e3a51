r"""Terms of a discovered force or rate: sympy expressions over a physics' own variables, evaluated in torch.

**Variables.** Second-order physics writes its terms in ``x``, ``v`` (position, velocity) and ``u``,
and they add to the acceleration; any other physics writes them in its own ``state_names`` and ``u``,
and each adds to the rate of a named state equation (:func:`variables_of`).

**A term** is a sympy expression in those variables, parsed by :func:`compile_term`; symbols whose
name starts with ``eps`` are *widths*, positive parameters of a smoothed sign ``tanh(v/eps)``. The
functions are ``Abs``, ``sign``, ``sqrt``, ``tanh``, ``exp``, ``sin``, ``cos`` and powers; sympy prints
the canonical spelling (``"x**2*tanh(v/eps)"``, ``"sqrt(Abs(upper))"``).

**The generated library** (:class:`TermLibrary`, as PySINDy's ``feature_library``), for variables
$z$ and the states $s$ that may carry a sign (the velocity; every state of other physics):

* the monomials of the variables of degree 0 to ``degree`` (3);
* the monomials $m$ of degree at most ``degree - 1`` times $|s|$ and times $\tanh(s/\varepsilon_s)$;
* $\sqrt{|s|}$ for every state (an outflow through an opening, Torricelli's law);
* the user's ``terms``, written as sympy strings.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import sympy
import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._errors import ConfigurationError
from torchpaml._physics.term_parser import parse_term

__all__ = ["CompiledTerm", "TermLibrary", "compile_term", "state_columns", "variables_of", "width_symbol"]

_FUNCTIONS: dict[type, Callable[[torch.Tensor], torch.Tensor]] = {
    sympy.Abs: torch.abs, sympy.sign: torch.sign, sympy.tanh: torch.tanh, sympy.exp: torch.exp,
    sympy.sin: torch.sin, sympy.cos: torch.cos,
}


def input_variables(physics: AbstractPhysics) -> tuple[str, ...]:
    """The names a term reads the inputs by: ``u`` for one input, ``u1, u2, …`` for several."""
    count = physics.input_dim
    return ("u",) if count == 1 else tuple(f"u{i + 1}" for i in range(count))


def input_values(physics: AbstractPhysics, u: torch.Tensor) -> dict[str, torch.Tensor]:
    """Each input variable's values (:func:`input_variables`) from ``u`` (..., n_input)."""
    return {name: u[..., i] for i, name in enumerate(input_variables(physics))}


def variables_of(physics: AbstractPhysics) -> tuple[tuple[str, ...], dict[str, int]]:
    """``(variables, equations)`` of a physics (module docstring): the names a term is written in, and each
    equation's name with the index of the state whose rate it adds to.

    Second-order physics: ``(("x", "v", "u"), {"acceleration": 1})``; any other: its ``state_names`` and its inputs
    (``u``, or ``u1, u2, …``: :func:`input_variables`), and one equation per state.
    """
    from torchpaml._physics.base import SecondOrderPhysics

    base = physics.without_effects()
    inputs = input_variables(base)
    if isinstance(base, SecondOrderPhysics):
        return ("x", "v", *inputs), {"acceleration": 1}
    names = tuple(base.state_names)
    bad = [n for n in names if not n.isidentifier() or n == "u" or n in inputs or n.startswith("eps")]
    if bad:
        raise ConfigurationError(f"{base.display_name}'s state names {bad} cannot name variables of a term; give state_names "
                         f"that are Python identifiers other than the inputs {list(inputs)} and 'u', not starting "
                         f"with 'eps'")
    return (*names, *inputs), {name: i for i, name in enumerate(names)}


def state_columns(physics: AbstractPhysics) -> dict[str, int]:
    """Each state variable's column in the state vector: ``{"x": 0, "v": 1}`` for second-order physics, else
    ``{state name: index}``."""
    _, equations = variables_of(physics)
    return {"x": 0, "v": 1} if "acceleration" in equations else dict(equations)


def width_symbol(variable: str) -> str:
    """The width of the smoothed sign of ``variable``: ``eps`` for the velocity ``v``, else ``eps_<variable>``."""
    return "eps" if variable == "v" else f"eps_{variable}"


@dataclass(frozen=True)
class CompiledTerm:
    """A parsed term: its canonical text, the widths it uses, and a torch function of the variables."""

    text: str
    widths: tuple[str, ...]
    evaluate: Callable[[dict[str, torch.Tensor]], torch.Tensor]


def _compile(node: sympy.Basic, text: str) -> Callable[[dict], torch.Tensor]:
    """A torch function of ``{symbol name: tensor}`` computing ``node``; ``ValueError`` for what it cannot run."""
    if node.is_Symbol:
        return lambda values, name=node.name: values[name]
    if node.is_Number:
        return lambda values, number=float(node): number
    if node.is_Add or node.is_Mul:  # sympy's printing order: node.args follow the strings' hashes, which vary by run
        ordered = node.as_ordered_terms() if node.is_Add else node.as_ordered_factors()
        parts = [_compile(arg, text) for arg in ordered]
        combine = (lambda a, b: a + b) if node.is_Add else (lambda a, b: a * b)

        def joined(values, parts=parts, combine=combine):
            result = parts[0](values)
            for part in parts[1:]:
                result = combine(result, part(values))
            return result
        return joined
    if node.is_Pow:
        base, exponent = node.args
        if not exponent.is_Number:
            raise ConfigurationError(f"term {text!r}: the exponent {exponent} must be a number")
        inner, power = _compile(base, text), float(exponent)
        if power == 0.5:
            return lambda values: torch.sqrt(inner(values))
        if power == int(power):
            return lambda values: inner(values) ** int(power)
        return lambda values: inner(values) ** power
    function = _FUNCTIONS.get(type(node))
    if function is not None:
        inner = _compile(node.args[0], text)
        return lambda values: function(inner(values))
    raise ConfigurationError(f"term {text!r}: {type(node).__name__} is not supported; write terms with +, *, **, Abs, sign, "
                     f"sqrt, tanh, exp, sin, cos")


def compile_term(text: str, variables: Sequence[str] | None) -> CompiledTerm:
    """Parse ``text`` (:func:`~torchpaml._physics.term_parser.parse_term`: read as data, never run) over
    ``variables`` (and widths ``eps...``; ``None``: any name); its canonical text and function.

    Raises :class:`~torchpaml.ConfigurationError` naming the term and the fix: a construct outside the parser's
    whitelist, unknown names, a constant that does not depend on any variable other than ``"1"``.
    """
    expression = parse_term(text)
    used = {s.name for s in expression.free_symbols}
    unknown = sorted(n for n in used if variables is not None and n not in variables and not n.startswith("eps"))
    if unknown:
        raise ConfigurationError(f"term {text!r} uses {unknown}, which are not variables of this physics; its variables are "
                         f"{list(variables)} (and widths named eps...)")
    if expression.is_Number and expression != 1:
        raise ConfigurationError(f"term {text!r} is a number; write the constant term as '1' (its coefficient is fitted)")
    canonical = str(expression)
    function = _compile(expression, canonical)
    like = sorted(n for n in used if not n.startswith("eps"))

    def evaluate(values: dict[str, torch.Tensor]) -> torch.Tensor:
        value = function(values)
        if like:
            return value
        shape = next(v for k, v in values.items() if not k.startswith("eps"))  # a constant: the variables' shape
        return torch.full_like(shape, float(value)) if not torch.is_tensor(value) else value.expand_as(shape)

    return CompiledTerm(canonical, tuple(sorted(n for n in used if n.startswith("eps"))), evaluate)


def _monomials(variables: Sequence[str], degree: int) -> list[str]:
    """The monomials of ``variables`` of degree 0 to ``degree``, in sympy's spelling, ``"1"`` first."""
    terms = ["1"]
    for d in range(1, degree + 1):
        for combo in itertools.combinations_with_replacement(variables, d):
            terms.append(str(math.prod(sympy.Symbol(n, real=True) for n in combo)))
    return terms


@dataclass(frozen=True)
class TermLibrary:
    """The terms discovery regresses on (module docstring): a pluggable feature library.

    Args:
        degree: highest total degree of the monomials (the sign-like products go one lower).
        signs: include the products with $|s|$ and $\\tanh(s/\\varepsilon_s)$.
        roots: include $\\sqrt{|s|}$ of every state.
        terms: the user's own terms, sympy strings over the physics' variables.
    """

    degree: int = 3
    signs: bool = True
    roots: bool = True
    terms: tuple[str, ...] = ()

    def build(self, physics: AbstractPhysics) -> list[str]:
        """The library's terms for ``physics`` (canonical sympy text, no duplicates, in a fixed order)."""
        variables, equations = variables_of(physics)
        inputs = input_variables(physics.without_effects())
        states = ("v",) if "acceleration" in equations else tuple(v for v in variables if v not in inputs)
        roots = ("x", "v") if "acceleration" in equations else states
        terms = _monomials(variables, self.degree)
        if self.signs:
            lower = _monomials(variables, self.degree - 1)
            for s in states:
                sign = sympy.tanh(sympy.Symbol(s, real=True) / sympy.Symbol(width_symbol(s), real=True))
                for m in lower:
                    factor = parse_term(m)
                    terms += [str(factor * sympy.Abs(sympy.Symbol(s, real=True))), str(factor * sign)]
        if self.roots:
            terms += [f"sqrt(Abs({s}))" for s in roots]
        terms += [compile_term(t, variables).text for t in self.terms]
        return list(dict.fromkeys(terms))
