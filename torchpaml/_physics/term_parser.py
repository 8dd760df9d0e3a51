r"""A term's text read as data: the one parser of every term that comes from a file, a config or the command line.

A term is parsed by Python's :mod:`ast` (``mode="eval"``: a single expression, never run) and the tree is walked
node by node against a whitelist; the sympy expression is built from the tree, so no text reaches ``eval``
(``sympy.sympify`` calls ``eval``: a term such as ``__import__('os').system(...)`` would run there). Allowed:

* numbers (``int`` and ``float`` literals);
* names: identifiers not starting with ``_`` (the physics' variables and widths ``eps...``: the caller checks
  which);
* ``+ - * / **`` and a leading ``-`` or ``+``; an exponent is a number of magnitude at most :data:`MAX_EXPONENT`;
* calls of the functions :data:`FUNCTIONS` (``Abs``, ``abs``, ``sign``, ``sqrt``, ``tanh``, ``exp``, ``sin``,
  ``cos``) with one positional argument.

Anything else (attributes, subscripts, strings, keywords, comparisons, lambdas, other calls) is refused in one line
that names the construct, as is a text longer than :data:`MAX_LENGTH` characters.
"""

from __future__ import annotations

import ast

import sympy

from torchpaml._errors import ConfigurationError

__all__ = ["FUNCTIONS", "MAX_EXPONENT", "MAX_LENGTH", "parse_term"]

#: The functions a term may call, by the name it is written with.
FUNCTIONS = {"Abs": sympy.Abs, "abs": sympy.Abs, "sign": sympy.sign, "sqrt": sympy.sqrt, "tanh": sympy.tanh,
             "exp": sympy.exp, "sin": sympy.sin, "cos": sympy.cos}
#: The largest magnitude of an exponent (``x**3``): larger powers are no physics and only cost time.
MAX_EXPONENT = 64
#: The longest term text read.
MAX_LENGTH = 2000

_OPERATORS = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
              ast.Div: lambda a, b: a / b}
_WRITE = "write terms with numbers, variable names, + - * / ** and " + ", ".join(FUNCTIONS)


def _refused(text: str, what: str) -> ConfigurationError:
    return ConfigurationError(f"term {text!r}: {what} is not allowed in a term; {_WRITE}")


def _number(value: object, text: str) -> sympy.Expr:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _refused(text, f"the constant {value!r}")
    return sympy.Integer(value) if isinstance(value, int) else sympy.Float(value)


def _build(node: ast.AST, text: str) -> sympy.Expr:
    """The sympy expression of the whitelisted tree ``node`` (module docstring)."""
    if isinstance(node, ast.Constant):
        return _number(node.value, text)
    if isinstance(node, ast.Name):
        if node.id.startswith("_"):
            raise _refused(text, f"the name {node.id!r} (names starting with '_')")
        return sympy.Symbol(node.id, real=True)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        inner = _build(node.operand, text)
        return -inner if isinstance(node.op, ast.USub) else inner
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
        exponent = _build(node.right, text)
        if not exponent.is_Number or abs(float(exponent)) > MAX_EXPONENT:
            raise ConfigurationError(f"term {text!r}: the exponent {exponent} must be a number of magnitude at most "
                                     f"{MAX_EXPONENT}")
        return _build(node.left, text) ** exponent
    if isinstance(node, ast.BinOp) and type(node.op) in _OPERATORS:
        return _OPERATORS[type(node.op)](_build(node.left, text), _build(node.right, text))
    if isinstance(node, ast.Call):
        name = node.func.id if isinstance(node.func, ast.Name) else None
        if name not in FUNCTIONS or node.keywords or len(node.args) != 1:
            shown = name or type(node.func).__name__.lower()
            raise _refused(text, f"the call {shown}(...)" if name not in FUNCTIONS else
                           f"{name} with {len(node.args)} argument(s) or keywords")
        return FUNCTIONS[name](_build(node.args[0], text))
    raise _refused(text, f"{type(node).__name__.lower()} ({ast.unparse(node)[:40]!r})")


def parse_term(text: str) -> sympy.Expr:
    """The sympy expression of the term ``text`` (module docstring); every name a real ``sympy.Symbol``.

    Raises :class:`~torchpaml.ConfigurationError` in one line for text that is not a term: a syntax error, a
    construct outside the whitelist, a text over :data:`MAX_LENGTH` characters."""
    if not isinstance(text, str):
        raise ConfigurationError(f"a term is text, like 'x**2*tanh(v/eps)'; got {type(text).__name__} {text!r}")
    if len(text) > MAX_LENGTH:
        raise ConfigurationError(f"term {text[:40]!r}... is {len(text)} characters long; a term has at most "
                                 f"{MAX_LENGTH}")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as error:
        raise ConfigurationError(f"term {text!r} is not an expression ({error.msg}); write it like "
                                 "'x**2*tanh(v/eps)'") from None
    return _build(tree.body, text)
