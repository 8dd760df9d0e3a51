"""Subexpressions of the parameters alone are lifted out of the per-stage functions (torchpaml._symbolic.hoist): the
lifted forms, with the lifted values put back, are the original expressions, and no lifted value depends on a
variable; each lifted symbol names its own element past the parameters. Checked by substitution (exact, symbolic) and by evaluation at random points (within 1e-15 relative: the
products and sums that held a lifted subexpression now take it as one factor or term, a rounding's difference)."""

import random

import sympy

from torchpaml._symbolic.hoist import hoisted, slot

t, x, v, u = (sympy.Symbol(name, real=True) for name in ("t_", "x_[0]", "x_[1]", "u_[0]"))
p = [sympy.Symbol(f"p_[{k}]", real=True) for k in range(3)]
EXPRESSIONS = [
    -2 * v * sympy.exp(p[0]) * sympy.exp(p[1]) - x * sympy.exp(2 * p[1]) - p[2] * x**3 + u,
    sympy.Piecewise((sympy.sqrt(sympy.exp(p[0])) * x, x > 2 * p[1]), (0, True)),
    sympy.sin(t) * sympy.log(1 + sympy.exp(p[2])) + p[0],
    sympy.exp(p[0]) + sympy.exp(p[1]),  # the parameters alone: lifted whole
]


def test_the_lifted_expressions_are_the_original_ones():
    (lifted,), constants = hoisted([EXPRESSIONS], {t, x, v, u}, 3)
    symbols = {s for e in lifted for s in e.free_symbols if slot(s) is not None}
    back = {s: constants[slot(s) - 3] for s in symbols}
    assert sorted(slot(s) for s in symbols) == list(range(3, 3 + len(constants)))
    assert all(not (c.free_symbols & {t, x, v, u}) for c in constants)
    assert [e.xreplace(back) for e in lifted] == EXPRESSIONS
    assert lifted[3] in back  # the parameters alone: one lifted value
    assert not any(e.has(sympy.exp) for e in lifted)  # every exponential of a parameter is lifted
    generator = random.Random(0)
    for _ in range(20):
        point = {s: generator.uniform(-1.5, 1.5) for s in (t, x, v, u, *p)}
        values = {**point, **{s: float(c.subs(point)) for s, c in back.items()}}
        for original, form in zip(EXPRESSIONS, lifted, strict=True):
            expected = float(original.subs(point))
            assert abs(float(form.subs(values)) - expected) <= 1e-15 * max(1.0, abs(expected))


def test_the_same_subexpression_is_lifted_once_across_groups():
    shared = sympy.exp(p[0]) * x
    _, constants = hoisted([[shared], [shared + u]], {t, x, v, u}, 3)
    assert constants == [sympy.exp(p[0])]
