r"""The output of a record and its sensitivities to named parameters, by the one simulator.

$J_{t,j} = \partial \hat y_t / \partial \rho_j$ for the raw (unconstrained) parameters $\rho_j$:

* linear physics on a uniform grid: by the sensitivity recurrence of the exact discretisation. With
  $x_{k+1} = \Phi x_k + \Gamma_0 u_k + \Gamma_1 u_{k+1}$ and $y_k = C x_k + D u_k$, the state's sensitivity
  $S_k = \partial x_k/\partial\rho_j$ obeys the same filter driven by the matrices' derivatives along the states,

  $$ S_{k+1} = \Phi S_k + \Phi' x_k + \Gamma_0' u_k + \Gamma_1' u_{k+1}, \qquad S_0 = 0, \qquad
     \partial y_k/\partial\rho_j = C S_k + C' x_k + D' u_k, $$

  so one run of that recurrence (the parallel scan of the states) with a row per column gives them all, after
  one run for the states. The primed
  matrices come from central differences of (A, B, C, D) and the exponential's Fréchet derivative;
* otherwise: Newton runs once (:func:`~torchpaml._simulate.shooting.solve_shooting`, RK4 or TR-BDF2), then
  each column is a central difference of two single sweeps from the converged starts plus the
  implicit-function correction (:meth:`~torchpaml._simulate.shooting.ShootingSolution.states`), not of
  whole simulations.

Central differences take the step :func:`~torchpaml._simulate.differences.difference_step` (error ~1e-10 relative).

Differences, not forward mode: on torch 2.13, forward-mode AD sends every operation that mixes a
dual tensor with a Python number through Python decompositions, about a hundred times slower than the
operation itself, and a physics' step is full of them. On the exact path the recurrence needs two
scans for all columns, where differences of whole simulations need 2p + 1.

With ``initial_state=True`` the Jacobian gains one column per state, $\partial\hat y_t/\partial x_{0,i}$:
on the exact path the free response $C\Phi^k e_i$ (rows of the same scan with $S_0 = e_i$), in
the engine the same passes as the parameters' with the initial state as the direction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from torch import nn
from torch.func import functional_call

from torchpaml._errors import ConfigurationError
from torchpaml._grid import check_hold
from torchpaml._simulate.differences import difference_step
from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.lti import discrete_states, discretize, exact_step, foh_exponent
from torchpaml._simulate.scan import constant_recurrence
from torchpaml._simulate.method import Method
from torchpaml._simulate.shooting import solve_shooting
from torchpaml._simulate.blowup import checked_output
from torchpaml._simulate.warm import WarmStart

__all__ = ["difference_jacobian", "exact_jacobian", "raw_parameters", "shooting_jacobian"]


def raw_parameters(physics: Dynamics, names: Sequence[str]) -> dict[str, torch.Tensor]:
    """``{functional_call key: raw tensor}`` for the physical parameters ``names`` (their unconstrained originals)."""
    keys = {id(p): key for key, p in physics.named_parameters()}
    raw = {}
    for name in names:
        owner, leaf = physics._owner(name)
        original = getattr(owner.parametrizations, leaf).original
        raw[keys[id(original)]] = original
    return raw


class _Run(nn.Module):
    """A trajectory of the physics and its output map, as a module for ``functional_call`` (the physics' parameters
    replaced while it runs)."""

    def __init__(self, physics: Dynamics, trajectory: Callable[[torch.Tensor], torch.Tensor], x0: torch.Tensor,
                 u: torch.Tensor):
        super().__init__()
        self.physics, self.trajectory, self.x0, self.u = physics, trajectory, x0, u

    def forward(self) -> torch.Tensor:
        return self.physics.output(self.trajectory(self.x0), self.u)


class _StateSpace(nn.Module):
    """The matrices (A, B, C, D) of linear physics, flattened into one vector (for ``functional_call``)."""

    def __init__(self, physics: Dynamics):
        super().__init__()
        self.physics = physics

    def forward(self) -> torch.Tensor:
        return torch.cat([m.flatten() for m in self.physics.state_space()])

    def unflatten(self, flat: torch.Tensor) -> list[torch.Tensor]:
        """The vector of :meth:`forward` (or derivatives of it, (..., length)) -> A, B, C, D, (..., rows, columns)."""
        n, m, p = self.physics.state_dim, self.physics.input_dim, self.physics.output_dim
        shapes = [(n, n), (n, m), (p, n), (p, m)]
        parts = flat.split([a * b for a, b in shapes], dim=-1)
        return [part.reshape(*flat.shape[:-1], *shape) for part, shape in zip(parts, shapes, strict=True)]


def _discretised_derivatives(physics: Dynamics, raw: dict[str, torch.Tensor], h: float, hold: str):
    r"""$(\Phi, \Gamma_0, \Gamma_1, C, D)$ for the input's ``hold`` and their derivatives in each raw parameter,
    stacked (p, ...).

    The derivatives of (A, B, C, D) are central differences; those of the discretisation follow from
    the Fréchet derivative of the exponential, $\exp\begin{pmatrix} M & E \\ 0 & M\end{pmatrix} =
    \begin{pmatrix} e^M & L(M, E) \\ 0 & e^M\end{pmatrix}$ with $E = \partial M/\partial\rho_j$, all
    parameters in one batched exponential.
    """
    module = _StateSpace(physics)
    A, B, C, D = module.unflatten(module())
    Phi, G0, G1 = discretize(A, B, h, hold)
    flats = [_directional(lambda r, key=key: functional_call(module, {f"physics.{key}": r}, ()), value.detach(),
                          torch.ones_like(value)) for key, value in raw.items()]
    if not flats:
        return (Phi, G0, G1, C, D), None
    dA, dB, dC, dD = module.unflatten(torch.stack(flats))
    n, m = B.shape
    size = n + 2 * m
    blocks = torch.zeros(len(flats), 2 * size, 2 * size, dtype=A.dtype)
    blocks[:, :size, :size] = blocks[:, size:, size:] = foh_exponent(A, B, h)
    blocks[:, :size, size:] = foh_exponent(dA, dB, h, ramp=False)
    L = torch.linalg.matrix_exp(blocks)[:, :n, size:]
    dPhi, dGa, dGb = L[..., :n], L[..., n : n + m], L[..., n + m :]
    if hold == "zoh":
        return (Phi, G0, G1, C, D), (dPhi, dGa, torch.zeros_like(dGb), dC, dD)
    return (Phi, G0, G1, C, D), (dPhi, dGa - dGb, dGb, dC, dD)


def _exact_jacobian(physics: Dynamics, raw: dict[str, torch.Tensor], h: float, t: torch.Tensor, u: torch.Tensor,
                    x0: torch.Tensor, initial_state: bool, hold: str) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`output_jacobian` on the exact path, by the sensitivity recurrence (module docstring)."""
    with torch.no_grad():
        (Phi, G0, G1, C, D), derivatives = _discretised_derivatives(physics, raw, h, hold)
        n, batch = Phi.shape[0], u.shape[0]
        states = discrete_states(Phi, G0, G1, u, x0)  # (batch, time, n)
        y = checked_output(states @ C.T + u @ D.T, t)
        drives, starts, direct = [], [], []
        if derivatives is not None:
            dPhi, dG0, dG1, dC, dD = (d[:, None] for d in derivatives)  # (p, 1, rows, columns)
            ahead = torch.cat([u[:, 1:], u[:, -1:]], dim=1)  # u_{k+1}; its last row drives nothing that is output
            drives.append(states @ dPhi.mT + u @ dG0.mT + ahead @ dG1.mT)  # (p, batch, time, n)
            starts.append(torch.zeros(len(dPhi), *x0.shape, dtype=x0.dtype))
            direct.append(states @ dC.mT + u @ dD.mT)
        if initial_state:  # the free response C Phi^k e_i
            drives.append(torch.zeros(n, *states.shape, dtype=x0.dtype))
            starts.append(torch.eye(n, dtype=x0.dtype)[:, None].expand(n, batch, n))
            direct.append(torch.zeros(n, *y.shape, dtype=y.dtype))
        drives, starts = torch.cat(drives), torch.cat(starts)
        # S_{k+1} = Phi S_k + drive_k: the last sample's drive reaches no output
        responses = constant_recurrence(Phi, drives.flatten(0, 1)[:, :-1], starts.flatten(0, 1)) @ C.T
        J = responses.reshape(len(drives), *y.shape) + torch.cat(direct)
    return y, J.movedim(0, -1)


def _directional(function, value: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
    """The derivative of ``function`` at ``value`` along ``direction``, by a central difference."""
    step = difference_step(float(value.abs().max()))
    with torch.no_grad():
        return (function(value + step * direction) - function(value - step * direction)) / (2 * step)


def exact_jacobian(physics: Dynamics, raw: dict[str, torch.Tensor], t: torch.Tensor, u: torch.Tensor,
                   x0: torch.Tensor, initial_state: bool, hold: str) -> tuple[torch.Tensor, torch.Tensor]:
    """Output and Jacobian (:meth:`~torchpaml.Solver.jacobian`) of linear physics on a uniform grid, by the
    sensitivity recurrence of the exact discretisation (module docstring)."""
    h = exact_step(physics, t)
    if h is None:
        raise ConfigurationError(f"the exact path needs linear physics on a uniform grid; {physics.display_name} is "
                                 "nonlinear or the grid is not uniform. Use Auto() or RK4()")
    return _exact_jacobian(physics, raw, h, t, u, x0.detach(), initial_state, check_hold(hold))


def shooting_jacobian(physics: Dynamics, raw: dict[str, torch.Tensor], t: torch.Tensor, u: torch.Tensor,
                      x0: torch.Tensor, method: Method, warm: WarmStart | None, initial_state: bool,
                      hold: str) -> tuple[torch.Tensor, torch.Tensor]:
    """Output and Jacobian (:meth:`~torchpaml.Solver.jacobian`) by the shooting engine at ``method``'s substeps:
    one Newton solve, then each column a central difference of single sweeps from the converged starts
    (module docstring)."""
    solution = solve_shooting(physics, t, u, x0, method, warm=warm, hold=hold)
    return difference_jacobian(physics, raw, u, x0, initial_state, lambda x: solution.states(physics, x))


def difference_jacobian(physics: Dynamics, raw: dict[str, torch.Tensor], u: torch.Tensor, x0: torch.Tensor,
                        initial_state: bool, trajectory: Callable[[torch.Tensor], torch.Tensor]
                        ) -> tuple[torch.Tensor, torch.Tensor]:
    """Output and Jacobian by central differences of ``trajectory`` (x0 (batch, n) -> states (batch, time, n) under
    the physics' current parameters), one column per raw parameter, then per state with ``initial_state``: what
    any solver's states give (:meth:`~torchpaml.Solver.jacobian`)."""
    module = _Run(physics, trajectory, x0, u)

    def from_state(x):
        return physics.output(trajectory(x), u)

    columns = []
    for key, value in raw.items():
        def output(r, key=key):
            return functional_call(module, {f"physics.{key}": r}, ())

        columns.append(_directional(output, value.detach(), torch.ones_like(value)))
    if initial_state:
        for direction in torch.eye(x0.shape[-1], dtype=x0.dtype):
            columns.append(_directional(from_state, x0.detach(), direction.expand_as(x0)))
    with torch.no_grad():
        y = from_state(x0.detach())
    return y, torch.stack(columns, dim=-1)
