r"""The model's one-step map as an ONNX graph, built from the closed form node by node (``onnx.helper``).

The graph maps ``t`` (1,), ``x`` (n,), ``u0`` (m,), ``u1`` (m,) and ``h`` (1,), all float64, to ``x_next`` (n,),
the state one sample later by the model's RK4 step (:func:`~torchpaml._export.code.python_code`'s ``step``), and
``y`` (p,), the output $h(x, u_0)$ at the current sample. A hybrid's residual adds its filter's states after the
physics' in ``x`` (zero at the start) and its output to ``y`` (:mod:`~torchpaml._export.residual_step`: exact at the
records' sampling interval, which ``h`` must then be). Run it in a loop (onnxruntime, or any ONNX runtime) to
simulate a record: $y_k$ from $x_k$, then $x_{k+1}$. Each sympy operation of the closed form becomes ONNX nodes
(:data:`FUNCTIONS`, arithmetic, powers, ``Piecewise`` as ``Where``); its common subexpressions are computed once
(``sympy.cse``). An operation without an ONNX node is refused in one line naming it.
"""

from __future__ import annotations

from pathlib import Path

import sympy

from torchpaml._errors import ConfigurationError
from torchpaml._export.code import ExportedStep

__all__ = ["FUNCTIONS", "write_onnx"]

#: sympy function -> the ONNX operator that computes it elementwise.
FUNCTIONS = {sympy.sin: "Sin", sympy.cos: "Cos", sympy.tan: "Tan", sympy.asin: "Asin", sympy.acos: "Acos",
             sympy.atan: "Atan", sympy.sinh: "Sinh", sympy.cosh: "Cosh", sympy.tanh: "Tanh", sympy.exp: "Exp",
             sympy.log: "Log", sympy.Abs: "Abs", sympy.sign: "Sign"}
RELATIONS = {sympy.StrictGreaterThan: "Greater", sympy.StrictLessThan: "Less", sympy.GreaterThan: "GreaterOrEqual",
             sympy.LessThan: "LessOrEqual", sympy.Equality: "Equal"}


class _Graph:
    """ONNX nodes emitted for sympy expressions, each value a float64 tensor of shape (1,)."""

    def __init__(self, owner: str):
        from onnx import helper

        self.helper, self.owner, self.nodes, self.count = helper, owner, [], 0

    def node(self, op: str, inputs: list[str], **attributes) -> str:
        self.count += 1
        name = f"v{self.count}"
        self.nodes.append(self.helper.make_node(op, inputs, [name], **attributes))
        return name

    def constant(self, value: float) -> str:
        from onnx import TensorProto

        tensor = self.helper.make_tensor(f"c{self.count + 1}", TensorProto.DOUBLE, [1], [float(value)])
        return self.node("Constant", [], value=tensor)

    def chain(self, op: str, names: list[str]) -> str:
        result = names[0]
        for name in names[1:]:
            result = self.node(op, [result, name])
        return result

    def emit(self, expr: sympy.Expr, env: dict[sympy.Symbol, str]) -> str:
        """The value name of ``expr``, ``env`` naming its symbols."""
        if expr in env:
            return env[expr]
        if expr.is_Number:
            return self.constant(float(expr))
        if isinstance(expr, sympy.Add):
            return self.chain("Add", [self.emit(a, env) for a in expr.args])
        if isinstance(expr, sympy.Mul):
            return self.chain("Mul", [self.emit(a, env) for a in expr.args])
        if isinstance(expr, sympy.Pow):
            base, exponent = expr.args
            if exponent == sympy.Rational(1, 2):
                return self.node("Sqrt", [self.emit(base, env)])
            return self.node("Pow", [self.emit(base, env), self.emit(exponent, env)])
        if isinstance(expr, (sympy.Max, sympy.Min)):
            return self.node("Max" if isinstance(expr, sympy.Max) else "Min", [self.emit(a, env) for a in expr.args])
        if isinstance(expr, sympy.Piecewise):
            return self._piecewise(expr.args, env)
        if expr.func in RELATIONS:
            return self.node(RELATIONS[expr.func], [self.emit(a, env) for a in expr.args])
        if expr.func in FUNCTIONS:
            return self.node(FUNCTIONS[expr.func], [self.emit(expr.args[0], env)])
        raise ConfigurationError(f"cannot export {self.owner} to ONNX: no ONNX operator for {expr.func.__name__} (in "
                                 f"{sympy.sstr(expr)[:80]}); export it as code or an FMU")

    def _piecewise(self, pieces, env) -> str:
        (value, condition), rest = pieces[0], pieces[1:]
        if condition == sympy.true or not rest:
            return self.emit(value, env)
        return self.node("Where", [self.emit(condition, env), self.emit(value, env), self._piecewise(rest, env)])

    def evaluate(self, expressions: list[sympy.Expr], env: dict[sympy.Symbol, str]) -> list[str]:
        """The value names of ``expressions``, their common subexpressions computed once."""
        shared, reduced = sympy.cse(list(expressions))
        env = dict(env)
        for symbol, expression in shared:
            env[symbol] = self.emit(expression, env)
        return [self.emit(e, env) for e in reduced]


def _split(graph: _Graph, name: str, count: int, prefix: str) -> list[str]:
    from onnx import TensorProto

    if count == 1:
        return [name]
    split = graph.helper.make_tensor(f"{prefix}_split", TensorProto.INT64, [count], [1] * count)
    sizes = graph.node("Constant", [], value=split)
    outputs = [f"{prefix}_{i}" for i in range(count)]
    graph.nodes.append(graph.helper.make_node("Split", [name, sizes], outputs, axis=0))
    return outputs


def _rk4(graph: _Graph, step: ExportedStep, t: str, x: list[str], u0: list[str], u1: list[str], h: str) -> list[str]:
    form = step.form
    rates = lambda time, state, inputs: graph.evaluate(  # noqa: E731
        list(form.rates), {form.time: time, **dict(zip(form.states, state)), **dict(zip(form.inputs, inputs))})
    d = graph.node("Div", [h, graph.constant(step.substeps)])
    half, sixth = graph.node("Mul", [d, graph.constant(0.5)]), graph.node("Div", [d, graph.constant(6.0)])
    slopes = [graph.node("Div", [graph.node("Sub", [b, a]), h]) if step.hold == "foh" else None
              for a, b in zip(u0, u1)]
    held = lambda offset: [a if s is None else graph.node("Add", [a, graph.node("Mul", [s, offset])])  # noqa: E731
                           for a, s in zip(u0, slopes)]
    axpy = lambda a, k, scale: [graph.node("Add", [ai, graph.node("Mul", [scale, ki])])  # noqa: E731
                                for ai, ki in zip(a, k)]
    for j in range(step.substeps):
        offset = graph.node("Mul", [d, graph.constant(j)])
        a, middle = graph.node("Add", [t, offset]), graph.node("Add", [offset, half])
        k1 = rates(a, x, held(offset))
        u_mid = held(middle)
        k2 = rates(graph.node("Add", [t, middle]), axpy(x, k1, half), u_mid)
        k3 = rates(graph.node("Add", [t, middle]), axpy(x, k2, half), u_mid)
        end = graph.node("Add", [offset, d])
        k4 = rates(graph.node("Add", [t, end]), axpy(x, k3, d), held(end))
        total = [graph.chain("Add", [p, graph.node("Mul", [graph.constant(2.0), q]),
                                     graph.node("Mul", [graph.constant(2.0), r]), s])
                 for p, q, r, s in zip(k1, k2, k3, k4)]
        x = axpy(x, total, sixth)
    return x


def write_onnx(step: ExportedStep, path: str | Path) -> Path:
    """Write the one-step map of ``step`` (module docstring) to ``path``; returns it."""
    try:
        import onnx
        from onnx import TensorProto, helper
    except ImportError:
        raise ConfigurationError("writing ONNX needs the onnx package: pip install torchpaml[export]") from None
    form, residual = step.form, step.residual
    n, m, p = len(form.states), len(form.inputs), len(form.outputs)
    extra = 0 if residual is None else len(residual.states)
    graph = _Graph(step.equation)
    states = _split(graph, "x", n + extra, "xs")
    x, z = states[:n], states[n:]
    u0, u1 = _split(graph, "u0", m, "u0s"), _split(graph, "u1", m, "u1s")
    x_next = _rk4(graph, step, "t", x, u0, u1, "h")
    y = graph.evaluate(list(form.output), {**dict(zip(form.states, x)), **dict(zip(form.inputs, u0))})
    if residual is not None:
        env = {**dict(zip(residual.states, z)), **dict(zip(form.inputs, u0)), **dict(zip(residual.following, u1))}
        x_next += graph.evaluate(list(residual.next_states), env)
        y = [graph.node("Add", [a, b]) for a, b in zip(y, graph.evaluate(list(residual.output), env))]
    graph.nodes.append(helper.make_node("Concat", x_next, ["x_next"], axis=0))
    graph.nodes.append(helper.make_node("Concat", y, ["y"], axis=0))
    value = lambda name, size: helper.make_tensor_value_info(name, TensorProto.DOUBLE, [size])  # noqa: E731
    model = helper.make_model(
        helper.make_graph(graph.nodes, "step", [value("t", 1), value("x", n + extra), value("u0", m), value("u1", m),
                                                value("h", 1)], [value("x_next", n + extra), value("y", p)]),
        producer_name="torchpaml", opset_imports=[helper.make_opsetid("", 17)])
    model.doc_string = f"{step.equation}: RK4, {step.substeps} substep(s) per sample, {step.hold} input"
    onnx.checker.check_model(model)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(model, str(path))
    return path
