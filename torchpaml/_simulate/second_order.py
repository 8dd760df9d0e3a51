r"""Second derivatives of a fixed-step simulation: reverse mode through every step of one segment.

**Why.** The first derivatives of both fast paths are exact: the shooting engine's implicit-function correction
$x + T\,\delta\xi$ (:mod:`~torchpaml._simulate.shooting`) and the compiled forward sensitivities
(:mod:`~torchpaml._simulate.compiled_gradient`). Their own derivatives are not: both hold the sensitivities $T$
(or $S$) constant. Measured on the hardening oscillator of the tests: a Hessian entry of -1.376 (central
differences of the gradient agree to 1e-6) came out as 0.0124 through the engine's correction.

**What.** Where a backward is itself differentiated (``create_graph=True``: a Hessian-vector product, a gradient
penalty), the states are simulated again as one segment from $x_0$ (:func:`one_segment`), whose graph is every
stage's and so differentiable to any order, and the vector-Jacobian product is taken through it, with its graph. A
plain backward passes straight to the fast path's first derivative. The cost is that of sequential eager steps with
their graph, about 1.5 ms per step of a 2-state model forward and backward (measured on one core: 15 s per 10^4 steps),
paid only when a second derivative is asked for; a progress line says how many steps it takes.
Forward mode passes the fast path's tangent through. Inside a ``torch.func`` transform (``jvp``, ``vmap``, ``hessian``)
the engine's graph is returned as it is: a custom function there needs rules of its own for each transform.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import torch

from torchpaml._simulate.compiled import transformed
from torchpaml._simulate.dynamics import Dynamics

__all__ = ["one_segment", "with_second_order"]

log = logging.getLogger(__name__)


def with_second_order(states: torch.Tensor, graph: Callable[[], torch.Tensor],
                      inputs: list[torch.Tensor]) -> torch.Tensor:
    """``states`` (their first derivative through their own graph), whose derivative of the backward is taken through
    ``graph()`` (the same states, differentiable to any order) in ``inputs``: every tensor the states depend on that
    requires a gradient."""
    if not torch.is_grad_enabled() or not inputs or transformed():
        return states
    return _SecondOrder.apply(states, graph, *inputs)


def one_segment(physics: Dynamics, layout, x0: torch.Tensor) -> torch.Tensor:
    """The states (batch, time, n) of ``layout`` (a :class:`~torchpaml._simulate.shooting._Layout` of one segment)
    swept from ``x0`` (batch, n) itself: the graph of every stage."""
    return layout.assemble(layout.sweep(physics, x0[None, :, None, :])[0])


class _SecondOrder(torch.autograd.Function):
    """``first`` with its backward passed through, and a differentiated backward through ``graph`` (module
    docstring)."""

    @staticmethod
    def forward(ctx, first, graph, *inputs):
        ctx.graph = graph
        ctx.save_for_backward(*inputs)
        return first.clone()

    @staticmethod
    def backward(ctx, grad):
        inputs = ctx.saved_tensors
        if not torch.is_grad_enabled():
            return grad, None, *[None] * len(inputs)
        log.info("a second derivative: the simulation again by reverse mode through each of its %d samples' steps "
                 "(about 1.5 ms a step)", grad.shape[1])
        found = torch.autograd.grad(ctx.graph(), inputs, grad, create_graph=True, allow_unused=True)
        return None, None, *found

    @staticmethod
    def jvp(ctx, first, _graph, *_inputs):
        return first
