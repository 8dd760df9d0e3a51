r"""What the solvers need of a model: the :class:`Dynamics` protocol, and the initial state it starts from.

The simulation layer sees tensors and this protocol only; :class:`~torchpaml.AbstractPhysics` (the layer above)
implements it, so that a physics can simulate itself (``physics(t, u)``) by importing the simulator, downwards.

$\dot x = f(t, x, u)$, $y = h(x, u)$: ``derivative`` is $f$ with t (rows,), x (rows, n_state), u (rows, n_input)
-> (rows, n_state); ``output`` is $h$ with x (..., n_state), u (..., n_input) -> (..., n_output).
"""

from __future__ import annotations

from typing import Protocol

import torch

from torchpaml._errors import ConfigurationError

__all__ = ["Dynamics", "complete_state"]


class Dynamics(Protocol):
    """A model the solvers integrate (module docstring); :class:`~torchpaml.AbstractPhysics` is one."""

    state_dim: int
    input_dim: int
    output_dim: int
    state_names: tuple[str, ...]
    display_name: str

    def derivative(self, t: torch.Tensor, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """$f(t, x, u)$: (rows,), (rows, n_state), (rows, n_input) -> (rows, n_state)."""

    def output(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """$h(x, u)$: (..., n_state), (..., n_input) -> (..., n_output)."""

    def initial_state(self, batch: int) -> torch.Tensor:
        """The state at rest, (batch, n_state)."""

    def state_space(self) -> tuple[torch.Tensor, ...] | None:
        """(A, B, C, D) of linear physics, ``None`` for nonlinear."""

    def linear_base(self) -> Dynamics | None:
        """The linear physics under this model's effects or learned force, whose exact trajectory starts Newton;
        ``None`` where there is none."""


def complete_state(physics: Dynamics, x0: torch.Tensor | None, batch: int) -> torch.Tensor:
    """The initial state (batch, n_state) to simulate ``physics`` from: rest (``physics.initial_state``) where
    ``x0`` is ``None``; ``x0`` itself; or, where ``x0`` holds only the first states (those of the base of
    ``physics + effect``), ``x0`` followed by the rest of ``physics.initial_state`` (the effects' own states at
    their declared initial values). Raises :class:`~torchpaml.ConfigurationError` for an ``x0`` with more states
    than the physics."""
    rest = physics.initial_state(batch if x0 is None else x0.shape[0])
    if x0 is None:
        return rest
    n, k = rest.shape[-1], x0.shape[-1]
    if k > n:
        raise ConfigurationError(f"x0 has {k} states, but {physics.display_name} has {n}: {list(physics.state_names)}")
    return x0 if k == n else torch.cat([x0, rest.to(x0)[..., k:]], dim=-1)
