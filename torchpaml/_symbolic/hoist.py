r"""Subexpressions of the parameters alone, lifted out of the functions that a compiled loop calls at every stage.

A physics' closed form is written in its raw parameters: a positive parameter appears as $e^{\rho}$, a damping term
as $2\,e^{\rho_\zeta} e^{\rho_\omega} v$. Printed as it is, every RK4 stage evaluates those exponentials again,
though they do not change within a simulation. :func:`hoisted` replaces each largest subexpression of the parameters
alone (a function of them, or the parameter factors of a product, the parameter terms of a sum, taken together) by
a symbol that C reads as ``p_[count + k]`` (:func:`slot`), an element past the parameters in the same array;
the compiled form's ``extend`` fills those elements once per call of a loop
(:func:`~torchpaml._simulate.compiled.extend_function`). Only the place of the arithmetic moves:
each lifted subexpression is evaluated as it was, the product or sum that held it then takes it as one factor or term.

The symbol's name begins with a digest of the subexpression, so a sum or product orders its terms by what they are,
never by ``k``: a model with an effect at zero strength added (whose parameters shift every ``k``) still sums the
other terms in the same order, to the same bits (``tests/unit/test_degrees_of_freedom.py``).
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Sequence

import sympy

__all__ = ["hoisted", "slot"]

_LIFTED = re.compile(r"lifted_[0-9a-f]{16}_(\d+)")


class _Lifter:
    """The lifted subexpressions, each once, in order; ``variables``: the symbols that change within a simulation."""

    def __init__(self, variables: set[sympy.Symbol], count: int):
        self.variables, self.count = variables, count
        self.lifted: dict[sympy.Expr, sympy.Symbol] = {}

    def constant(self, expression: sympy.Basic) -> bool:
        return isinstance(expression, sympy.Expr) and not (expression.free_symbols & self.variables)

    def symbol(self, expression: sympy.Expr) -> sympy.Symbol:
        if expression not in self.lifted:
            digest = hashlib.sha1(sympy.srepr(expression).encode()).hexdigest()[:16]
            self.lifted[expression] = sympy.Symbol(f"lifted_{digest}_{self.count + len(self.lifted)}", real=True)
        return self.lifted[expression]

    def __call__(self, expression: sympy.Basic) -> sympy.Basic:
        if expression.is_Atom:
            return expression
        if self.constant(expression):
            return self.symbol(expression)
        if isinstance(expression, (sympy.Mul, sympy.Add)):
            fixed = [a for a in expression.args if self.constant(a)]
            moving = [self(a) for a in expression.args if not self.constant(a)]
            if len(fixed) > 1 or (fixed and not fixed[0].is_Atom):
                fixed = [self.symbol(expression.func(*fixed))]
            return expression.func(*fixed, *moving)
        return expression.func(*[self(a) for a in expression.args])


def hoisted(groups: Sequence[Sequence[sympy.Expr]], variables: set[sympy.Symbol], count: int
            ) -> tuple[list[list[sympy.Expr]], list[sympy.Expr]]:
    """``groups`` of expressions with their subexpressions of the parameters alone (free of ``variables``: the time,
    states and inputs) replaced by the symbols of ``p_[count + k]`` (:func:`slot`), and those subexpressions in the
    order of ``k``."""
    lifter = _Lifter(variables, count)
    return [[lifter(e) for e in group] for group in groups], list(lifter.lifted)


def slot(symbol: sympy.Symbol) -> int | None:
    """The element of the parameter array that a lifted ``symbol`` is, ``None`` for any other symbol."""
    match = _LIFTED.fullmatch(symbol.name)
    return None if match is None else int(match.group(1))
