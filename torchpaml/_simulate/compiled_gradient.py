r"""The gradient of a compiled simulation: the states in C with their forward sensitivities, one pass.

**What.** Where a simulation records a derivative (in grad mode, a parameter or the initial state that requires a
gradient; in any mode, one that carries a forward tangent), the states $x_k$ (batch, time, n) come from the compiled
RK4 or TR-BDF2 (:mod:`~torchpaml._simulate.compiled_jacobian`) together with their sensitivities
$S_{k,c} = \partial x_k/\partial\theta_c$ to every parameter element $\theta_c$ so differentiated and, where $x_0$
is, to each initial state ($S_{k, p+i} = \partial x_k/\partial x_{0,i}$). They are the exact derivatives of the
discrete map that gave the states (the tests hold them to reverse mode through every torch stage within 1e-9), at C
speed. Then

* reverse mode (``backward``): $\bar\theta_c = \sum_{b,k} \bar x_{b,k} \cdot S_{b,k,c}$ (summed over the rows
  for a parameter, per row for an initial state);
* forward mode (``torch.autograd.forward_ad``): $\dot x_k = \sum_c S_{k,c}\,\dot\theta_c$;
* a differentiated backward (``create_graph=True``) goes through :mod:`~torchpaml._simulate.second_order`.

**Where it is used.** :func:`~torchpaml._simulate.shooting.simulate_shooting`, wherever the states without a
derivative are compiled (:func:`~torchpaml._simulate.compiled_jacobian.compiled_states`: the same path, so a
simulation's values do not depend on grad mode) and nothing else needs the engine: the input and the times carry no
derivative; no buffer, and no tensor attribute that is not a parameter, carries one (the closed form holds those as
numbers); at most :data:`MAX_COLUMNS` sensitivities. Otherwise ``None``, and the shooting engine records the graph.
Memory: $S$ holds batch x time x columns x n numbers (65 536 samples, 3 parameters, 2 states: 3 MB).
"""

from __future__ import annotations

import logging

import torch
from torch.autograd import forward_ad

from torchpaml._errors import SimulationError
from torchpaml._simulate.compiled import compiled_form
from torchpaml._simulate.compiled_jacobian import compiled_sensitivities, compiled_states
from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.method import Method

__all__ = ["MAX_COLUMNS", "compiled_gradient_states", "constants", "differentiated"]

log = logging.getLogger(__name__)

#: Most sensitivities (parameter elements and initial states) carried in C: each costs $n^2$ multiply-adds per stage,
#: and a network's hundreds of weights are cheaper by the engine's reverse mode.
MAX_COLUMNS = 32


def differentiated(tensor: torch.Tensor) -> bool:
    """Whether a derivative of ``tensor`` is recorded: it requires a gradient in grad mode, or it carries a forward
    tangent (``torch.autograd.forward_ad``, which runs in any grad mode)."""
    return (tensor.requires_grad and torch.is_grad_enabled()) or forward_ad.unpack_dual(tensor).tangent is not None


def constants(physics: Dynamics) -> list[torch.Tensor]:
    """The tensors of ``physics`` that its closed form holds as numbers: its buffers, and its tensor attributes that are
    not parameters."""
    return [v for module in physics.modules() for v in (*vars(module).values(), *module._buffers.values())
            if isinstance(v, torch.Tensor) and not isinstance(v, torch.nn.Parameter)]


def compiled_gradient_states(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, solver: Method,
                             hold: str) -> torch.Tensor | None:
    """The states (batch, time, n_state) of ``physics`` by ``solver``'s method in C, in the graph of the parameters and
    ``x0`` where they are :func:`differentiated` (module docstring), detached where nothing is; ``None`` where the
    engine records the graph."""
    if differentiated(u) or differentiated(t) or any(differentiated(v) for v in constants(physics)):
        return None
    parameters = [(name, p) for name, p in physics.named_parameters() if differentiated(p)]
    if not parameters and not differentiated(x0):
        return compiled_states(physics, t, u, x0, solver, hold)
    steps = u.shape[0] * (len(t) - 1) * solver.substeps  # as compiled_states: short records of RK4 stay on the engine
    compiled = compiled_sensitivities(physics, solver) if compiled_form(physics, solver, steps) is not None else None
    if compiled is None:
        return None
    form, run = compiled
    offsets = {name: (first, size) for name, first, size in form.targets}
    columns = [offsets[name][0] + k for name, p in parameters for k in range(p.numel())]
    if differentiated(x0):
        columns += [-1 - i for i in range(x0.shape[-1])]
    if len(columns) > MAX_COLUMNS:
        return None
    try:
        states, S = run.sensitive_states(solver.compiles, form.parameters(physics), columns, t, u, x0,
                                         solver.substeps, hold)
    except SimulationError as error:
        log.info("%s: %s in C; the torch engine simulates this one", physics.display_name, error)
        return None
    if not (bool(torch.isfinite(states).all()) and bool(torch.isfinite(S).all())):
        return None  # the engine reports where it blows up
    solved = states.to(x0.dtype), S.to(x0.dtype), differentiated(x0)
    return _Sensitive.apply(solved, x0, *[p for _, p in parameters])


class _Sensitive(torch.autograd.Function):
    """The states in the graph of ``x0`` and ``parameters`` (module docstring). ``solved``: the states, their
    sensitivities ``S`` (the parameters' elements in order, then ``x0``'s where its flag says so), that flag."""

    @staticmethod
    def forward(ctx, solved, x0, *parameters):
        states, S, ctx.x0_columns = solved
        ctx.save_for_backward(S)
        ctx.save_for_forward(S)
        ctx.shapes = [p.shape for p in parameters]
        return states

    @staticmethod
    def backward(ctx, grad):
        S, = ctx.saved_tensors
        weights = torch.einsum("btn,btcn->bc", grad, S)  # (batch, columns)
        found, at = [], 0
        for shape in ctx.shapes:
            size = shape.numel()
            found.append(weights[:, at: at + size].sum(0).reshape(shape))
            at += size
        return None, weights[:, at:] if ctx.x0_columns else None, *found

    @staticmethod
    def jvp(ctx, _solved, x0_tangent, *tangents):
        S, = ctx.saved_tensors
        batch = S.shape[0]
        columns = [S.new_zeros(shape.numel()) if v is None else v.reshape(-1)
                   for v, shape in zip(tangents, ctx.shapes, strict=True)]
        weights = torch.cat(columns)[None].expand(batch, -1) if columns else S.new_zeros(batch, 0)
        if ctx.x0_columns:
            weights = torch.cat([weights, S.new_zeros(batch, S.shape[-1]) if x0_tangent is None else x0_tangent], dim=1)
        return torch.einsum("btcn,bc->btn", S, weights)
