r"""The closed form of a physics: its rates $f(t, x, u)$ and its output $h(x, u)$ as sympy expressions.

``physics.derivative`` and ``physics.output`` run once on one row, and each ATen operation they reach is also
applied to numpy arrays of sympy expressions (:mod:`~torchpaml._symbolic.trace`), the inputs being the symbols
$t$, $x_i$ (the physics' state names) and $u_j$ (the input channels' names), the parameters their fitted values. Whatever the physics is written with (a user's class, library effects with their own states, a
discovered closed form), the result is one expression per rate and per output. An operation the table does not
know is refused in one line naming it (:class:`~torchpaml.ConfigurationError`).

Every exporter (:mod:`~torchpaml._export.code`, :mod:`~torchpaml._export.fmu`, :mod:`~torchpaml._export.onnx_step`)
prints this one closed form.
"""

from __future__ import annotations

import keyword
import re
from dataclasses import dataclass

import numpy as np
import sympy

from torchpaml._symbolic.trace import symbolic_maps
from torchpaml._physics.base import AbstractPhysics

__all__ = ["ClosedForm", "closed_form", "identifier"]


#: C's reserved words (C99 and its common headers' names the generated code uses), which no variable may take.
C_RESERVED = frozenset("""auto break case char const continue default do double else enum extern float for goto if
inline int long register restrict return short signed sizeof static struct switch typedef union unsigned void volatile
while _Bool _Complex _Imaginary math sqrt exp sin cos tanh fabs pow copysign""".split())


def identifier(name: str) -> str:
    """``name`` as an identifier of Python and C (``cubic_stiffness.z`` -> ``cubic_stiffness_z``); a reserved word
    of either language gets a trailing ``_`` (``if`` -> ``if_``)."""
    text = re.sub(r"\W", "_", name, flags=re.ASCII)
    text = text if text and not text[0].isdigit() else f"_{text}"
    return f"{text}_" if keyword.iskeyword(text) or text in C_RESERVED else text


@dataclass(frozen=True)
class ClosedForm:
    """A physics as expressions (module docstring).

    Attributes:
        time: the symbol $t$.
        states, inputs: the symbols $x$ (n_state) and $u$ (n_input), named after the physics' states and the
            model's input channels.
        outputs: the output channels' names (n_output).
        rates: $f(t, x, u)$, one expression per state.
        output: $h(x, u)$, one expression per output.
    """

    time: sympy.Symbol
    states: tuple[sympy.Symbol, ...]
    inputs: tuple[sympy.Symbol, ...]
    outputs: tuple[str, ...]
    rates: tuple[sympy.Expr, ...]
    output: tuple[sympy.Expr, ...]


def _names(given: tuple[str, ...], count: int, letter: str) -> list[str]:
    if len(given) == count:
        return [identifier(name) for name in given]
    return [letter] if count == 1 else [f"{letter}{i}" for i in range(1, count + 1)]


def closed_form(physics: AbstractPhysics, inputs: tuple[str, ...] = (), outputs: tuple[str, ...] = ()) -> ClosedForm:
    """The closed form of ``physics`` (module docstring); ``inputs`` and ``outputs`` name the channels (default
    ``u``/``y``, or the physics' own ``input_names``/``output_names``)."""
    n, m = physics.state_dim, physics.input_dim
    t = sympy.Symbol("t", real=True)
    x = [sympy.Symbol(name, real=True) for name in _names(tuple(physics.state_names), n, "x")]
    u = [sympy.Symbol(name, real=True) for name in _names(inputs or tuple(physics.input_names), m, "u")]
    values = {"t": np.array([t], dtype=object), "x": np.array([x], dtype=object), "u": np.array([u], dtype=object)}
    rates, output = symbolic_maps(physics, values)
    output_names = _names(outputs or tuple(physics.output_names), physics.output_dim, "y")
    return ClosedForm(t, tuple(x), tuple(u), tuple(output_names), tuple(rates.reshape(-1)),
                      tuple(output.reshape(-1)))
