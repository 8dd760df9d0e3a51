"""ATen operations on numpy arrays of sympy expressions: how a physics becomes its closed form.

:func:`~torchpaml._symbolic.trace.symbolic_maps` runs a physics and gives each tensor a twin: a numpy object array of
sympy expressions (the parameters and constants as numbers or symbols, the inputs as symbols). Each operation of
:data:`OPS` does to the twins what ATen does to tensors, element by element and with numpy's broadcasting. The table holds the
operations that physics is written with: arithmetic, powers, the elementary functions, comparisons and ``where``,
minimum and maximum, and the shape operations (select, slice, stack, cat, unbind, reshape, ...). An operation not
in it is refused in one line naming it.
"""

from __future__ import annotations

import operator
from collections.abc import Callable

import numpy as np
import sympy
import torch

__all__ = ["OPS", "as_array"]

aten = torch.ops.aten


def as_array(value) -> np.ndarray:
    """A tensor, a number or an array as a numpy object array of sympy expressions."""
    if isinstance(value, np.ndarray):
        return value
    if isinstance(value, torch.Tensor):
        numbers = value.detach().to(torch.float64).numpy()
        return np.vectorize(lambda v: sympy.Float(repr(float(v))), otypes=[object])(numbers) if numbers.size else \
            np.empty(numbers.shape, dtype=object)
    return np.array(sympy.sympify(value, strict=True), dtype=object)


def _elementwise(function: Callable) -> Callable:
    vector = np.vectorize(function, otypes=[object])
    return lambda *args, **kwargs: vector(*[as_array(a) for a in args])


def _binary(function: Callable) -> Callable:
    return lambda a, b, **kwargs: np.frompyfunc(function, 2, 1)(as_array(a), as_array(b))


def _scaled(function: Callable) -> Callable:
    """ATen's ``add``/``sub`` with their ``alpha``."""
    return lambda a, b, alpha=1: np.frompyfunc(function, 2, 1)(as_array(a), as_array(b) * alpha)


def _slice(a, dim=0, start=None, end=None, step=1):
    index = [slice(None)] * a.ndim
    index[dim] = slice(start, None if end is not None and end >= 2**62 else end, step)
    return a[tuple(index)]


def _sign(v):
    return sympy.sign(v)


def _where(condition, a, b):
    return np.frompyfunc(lambda c, x, y: sympy.Piecewise((x, c), (y, True)), 3, 1)(
        as_array(condition), as_array(a), as_array(b))


def _reduce(function: Callable) -> Callable:
    def reduce(a, dims=None, keepdim=False, dtype=None):
        axes = tuple(range(a.ndim)) if dims is None or len(dims) == 0 else tuple(d % a.ndim for d in dims)
        return function(a, axis=axes, keepdims=keepdim)
    return reduce


def _mean(a, axis, keepdims):
    count = int(np.prod([a.shape[i] for i in axis]))
    return np.sum(a, axis=axis, keepdims=keepdims) / count


def _full(size, value, **kwargs):
    return np.full(tuple(size), sympy.sympify(value, strict=True), dtype=object)


def _full_like(a, value, **kwargs):
    return np.full(a.shape, sympy.sympify(value, strict=True), dtype=object)


_SAME = lambda a, *args, **kwargs: a  # noqa: E731  operations that leave the values as they are

#: ATen operation -> its action on object arrays (module docstring).
OPS: dict = {
    aten.add.Tensor: _scaled(operator.add), aten.sub.Tensor: _scaled(operator.sub),
    aten.add.Scalar: _scaled(operator.add), aten.sub.Scalar: _scaled(operator.sub),
    aten.rsub.Scalar: lambda a, b, alpha=1: as_array(b) - as_array(a) * alpha,
    aten.mul.Tensor: _binary(operator.mul), aten.mul.Scalar: _binary(operator.mul),
    aten.div.Tensor: _binary(operator.truediv), aten.div.Scalar: _binary(operator.truediv),
    aten.neg.default: lambda a: -a, aten.reciprocal.default: _elementwise(lambda v: 1 / v),
    aten.pow.Tensor_Scalar: _binary(operator.pow), aten.pow.Tensor_Tensor: _binary(operator.pow),
    aten.pow.Scalar: _binary(operator.pow), aten.square.default: _elementwise(lambda v: v**2),
    aten.sqrt.default: _elementwise(sympy.sqrt), aten.rsqrt.default: _elementwise(lambda v: 1 / sympy.sqrt(v)),
    aten.exp.default: _elementwise(sympy.exp), aten.log.default: _elementwise(sympy.log),
    aten.log1p.default: _elementwise(lambda v: sympy.log(1 + v)), aten.expm1.default: _elementwise(lambda v: sympy.exp(v) - 1),
    aten.sin.default: _elementwise(sympy.sin), aten.cos.default: _elementwise(sympy.cos),
    aten.tan.default: _elementwise(sympy.tan), aten.atan.default: _elementwise(sympy.atan),
    aten.asin.default: _elementwise(sympy.asin), aten.acos.default: _elementwise(sympy.acos),
    aten.atan2.default: _binary(sympy.atan2),
    aten.sinh.default: _elementwise(sympy.sinh), aten.cosh.default: _elementwise(sympy.cosh),
    aten.tanh.default: _elementwise(sympy.tanh), aten.abs.default: _elementwise(sympy.Abs),
    aten.sign.default: _elementwise(_sign), aten.sgn.default: _elementwise(_sign),
    aten.sigmoid.default: _elementwise(lambda v: 1 / (1 + sympy.exp(-v))),
    aten.relu.default: _elementwise(lambda v: sympy.Max(0, v)),
    aten.softplus.default: lambda a, beta=1, threshold=20: _elementwise(
        lambda v: sympy.log(1 + sympy.exp(beta * v)) / beta)(a),
    aten.maximum.default: _binary(sympy.Max), aten.minimum.default: _binary(sympy.Min),
    aten.clamp.default: lambda a, lo=None, hi=None: _elementwise(
        lambda v: sympy.Min(sympy.Max(v, lo) if lo is not None else v, hi) if hi is not None else sympy.Max(v, lo))(a),
    aten.clamp_min.default: lambda a, lo: _elementwise(lambda v: sympy.Max(v, lo))(a),
    aten.clamp_max.default: lambda a, hi: _elementwise(lambda v: sympy.Min(v, hi))(a),
    aten.gt.Tensor: _binary(sympy.StrictGreaterThan), aten.gt.Scalar: _binary(sympy.StrictGreaterThan),
    aten.lt.Tensor: _binary(sympy.StrictLessThan), aten.lt.Scalar: _binary(sympy.StrictLessThan),
    aten.ge.Tensor: _binary(sympy.GreaterThan), aten.ge.Scalar: _binary(sympy.GreaterThan),
    aten.le.Tensor: _binary(sympy.LessThan), aten.le.Scalar: _binary(sympy.LessThan),
    aten.where.self: _where, aten.where.ScalarOther: _where, aten.where.ScalarSelf: _where, aten.where.Scalar: _where,
    aten.select.int: lambda a, dim, index: np.take(a, index, axis=dim),
    aten.slice.Tensor: _slice,
    aten.stack.default: lambda items, dim=0: np.stack([as_array(i) for i in items], axis=dim),
    aten.cat.default: lambda items, dim=0: np.concatenate([as_array(i) for i in items], axis=dim),
    aten.unbind.int: lambda a, dim=0: tuple(np.moveaxis(a, dim, 0)),
    aten.unsqueeze.default: lambda a, dim: np.expand_dims(a, dim % (a.ndim + 1)),
    aten.squeeze.dim: lambda a, dim: np.squeeze(a, dim) if a.shape[dim] == 1 else a,
    aten.squeeze.dims: lambda a, dims: np.squeeze(a, tuple(d for d in dims if a.shape[d] == 1)),
    aten.movedim.int: lambda a, source, destination: np.moveaxis(a, source, destination),
    aten.permute.default: lambda a, dims: np.transpose(a, dims),
    aten.transpose.int: lambda a, d0, d1: np.swapaxes(a, d0, d1),
    aten.t.default: lambda a: a.T,
    aten.view.default: lambda a, size: np.reshape(a, size), aten.reshape.default: lambda a, size: np.reshape(a, size),
    aten._unsafe_view.default: lambda a, size: np.reshape(a, size),
    aten.flatten.using_ints: lambda a, start=0, end=-1: np.reshape(
        a, a.shape[:start % a.ndim] + (-1,) + a.shape[end % a.ndim + 1:]),
    aten.expand.default: lambda a, size, implicit=False: np.broadcast_to(
        a, tuple(s if s != -1 else a.shape[i - len(size) + a.ndim] for i, s in enumerate(size))).copy(),
    aten.sum.dim_IntList: _reduce(np.sum), aten.sum.default: _reduce(np.sum), aten.mean.dim: _reduce(_mean),
    aten.mm.default: lambda a, b: np.matmul(a, b), aten.matmul.default: lambda a, b: np.matmul(a, b),
    aten.bmm.default: lambda a, b: np.matmul(a, b),
    aten.full.default: _full, aten.full_like.default: _full_like,
    aten.zeros.default: lambda size, **kw: _full(size, 0), aten.ones.default: lambda size, **kw: _full(size, 1),
    aten.zeros_like.default: lambda a, **kw: _full_like(a, 0), aten.ones_like.default: lambda a, **kw: _full_like(a, 1),
    aten.scalar_tensor.default: lambda value, **kw: np.array(sympy.sympify(value, strict=True), dtype=object),
    aten.alias.default: _SAME, aten.clone.default: _SAME, aten.detach.default: _SAME,
    aten.lift_fresh_copy.default: _SAME, aten._to_copy.default: _SAME, aten.to.dtype: _SAME,
    aten.contiguous.default: _SAME,
}
