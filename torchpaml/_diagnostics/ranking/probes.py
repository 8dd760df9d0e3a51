r"""Probe engines: the outputs of ``base + effect`` near the base, for the ranking's first-order scores.

* :class:`TangentLinear`: around a *linear* base on uniform records, the first-order outputs by the
  exact LTI path, one filter run per record for all of an effect's probe strengths;
* :class:`Secant`: otherwise, RK4 simulations warm-started from the base's trajectory.

Both answer ``outputs(extended)`` and ``probes(extended, name, values)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from torchpaml._data import Record
from torchpaml._errors import DataError, SimulationError
from torchpaml._physics.base import AbstractPhysics, complete_state
from torchpaml._grid import uniform_step
from torchpaml._simulate.lti import simulate_lti, simulate_lti_states
from torchpaml._simulate.solvers import Auto, Solver
from torchpaml._simulate.warm import WarmStart
from torchpaml._simulate.blowup import checked_output

__all__ = ["Secant", "TangentLinear", "assigned"]


def assigned(extended: AbstractPhysics, name: str, value: float) -> bool:
    """Set the strength ``name`` to ``value``; ``False`` (and unchanged) where its constraint forbids it."""
    try:
        extended.assign(**{name: value})
    except ValueError:
        return False
    return True


class TangentLinear:
    r"""First-order outputs of ``base + effect`` around a *linear* base, by the exact LTI path.

    With $\dot x = A x + B u + \Delta f_k(x, u)$ (the effect's change of the derivative: forces, rates
    and input maps) and $y = h_k(x, u)$, the output's change to first order in the strength $k$ is the
    base's own linear dynamics driven by $\Delta f_k$ along the baseline trajectory $x^0$, plus
    $h_k(x^0) - h_0(x^0)$:

    $$ \delta y = C\,(sI - A)^{-1}\, \Delta f_k(x^0, u) + h_k(x^0, u) - h_0(x^0, u). $$

    The probes of one effect are one exact simulation (a filter) per record, with a row per strength.
    """

    def __init__(self, base: AbstractPhysics, train: list[Record], initial_states: list[torch.Tensor]):
        A, B, C, _ = (m.detach() for m in base.state_space())
        n = A.shape[0]
        self.base, self.A, self.C = base, A, C
        self.records = []
        with torch.no_grad():
            for record, x0 in zip(train, initial_states, strict=True):
                h = uniform_step(record.t)
                u = record.u[None]
                states = simulate_lti_states(A, B, h, u, x0.reshape(1, n), record.hold)
                self.records.append((record.elapsed, u, states, h, record.hold))

    @classmethod
    def of(cls, base: AbstractPhysics, train: list[Record],
           initial_states: list[torch.Tensor]) -> TangentLinear | None:
        """The tangent-linear model when ``base`` is linear physics on uniform records, else ``None``."""
        if base.state_space() is None:
            return None
        try:
            return cls(base, train, initial_states)
        except DataError:
            return None

    def outputs(self, extended: AbstractPhysics) -> torch.Tensor:
        """The first-order outputs of ``extended`` (the base plus effects) on the training records, concatenated."""
        return self._responses(extended, [{}])[0]

    def probes(self, extended: AbstractPhysics, name: str, values: Sequence[float]) -> list[torch.Tensor | None]:
        """The first-order outputs with the strength ``name`` at each of ``values`` (``None`` where its constraint
        forbids the value), one filter run per record for all of them."""
        allowed = [value for value in values if assigned(extended, name, value)]
        responses = iter(self._responses(extended, [{name: value} for value in allowed]))
        return [next(responses) if value in allowed else None for value in values]

    def _responses(self, extended: AbstractPhysics, settings: list[dict[str, float]]) -> list[torch.Tensor]:
        """The first-order outputs of ``extended`` with each of ``settings`` assigned, one filter row each."""
        n = self.A.shape[0]
        parts = []
        with torch.no_grad():
            for t, u, states, h, hold in self.records:
                x, w = states[0], u[0]
                extras, maps = [], []
                for setting in settings:
                    extended.assign(**setting)
                    extras.append(extended.derivative(t, x, w) - self.base.derivative(t, x, w))
                    maps.append(extended.output(states, u)[0])
                response = simulate_lti(self.A, torch.eye(n, dtype=self.A.dtype), self.C,
                                        torch.zeros(self.C.shape[0], n, dtype=self.A.dtype), h, torch.stack(extras),
                                        hold=hold)
                parts.append((response + torch.stack(maps)).flatten(1))
        return list(torch.cat(parts, dim=1))


class Secant:
    """Outputs of ``base + effect`` near the base, by simulations in the shooting engine warm-started from the base's trajectory.

    For a nonlinear base (or non-uniform records), where :class:`TangentLinear` does not apply; ``solver``: the
    solver the base was fitted with, whose fixed-step method (:meth:`~torchpaml.Solver.stepping`) simulates the base
    and every probe alike, so that a probe at strength 0 reproduces the base's output (the exact path of a linear
    base would differ from the probes' steps by the method's error). A probe
    at a small strength stays close to the base, so Newton, started from the base's converged states,
    needs a sweep or two instead of the several of a cold start.
    """

    def __init__(self, base: AbstractPhysics, train: list[Record], initial_states: list[torch.Tensor],
                 solver: Solver):
        self.records, self.solver = [], Auto(start=solver).stepping()  # the base and its probes by one method
        with torch.no_grad():
            for record, x0 in zip(train, initial_states, strict=True):
                t, u, start, hold = record.elapsed, record.u[None], x0.reshape(1, -1), record.hold
                guess = self.solver.states(base, t, u, start, hold=hold)
                self.records.append((t, u, start, hold, guess))

    def outputs(self, extended: AbstractPhysics) -> torch.Tensor:
        """The outputs of ``extended`` on the training records, concatenated."""
        parts = []
        with torch.no_grad():
            for t, u, start, hold, guess in self.records:
                start = complete_state(extended, start, 1)  # an effect's own states start at their declared values
                states = self.solver.states(extended, t, u, start, warm=WarmStart(guess), hold=hold)
                parts.append(checked_output(extended.output(states, u), t).flatten())
        return torch.cat(parts)

    def probes(self, extended: AbstractPhysics, name: str, values: Sequence[float]) -> list[torch.Tensor | None]:
        """The outputs with the strength ``name`` at each of ``values``; ``None`` where its constraint forbids
        the value or the model blows up at it; raises :class:`~torchpaml.SimulationError` where it blows up
        at strength 0."""
        return [self._output_at(extended, name, value) for value in values]

    def _output_at(self, extended: AbstractPhysics, name: str, value: float) -> torch.Tensor | None:
        """The outputs at strength ``value``; ``None`` where its constraint forbids it or the simulation blows up at a
        strength other than 0 (an unstable sign of the strength: a negative lag)."""
        if not assigned(extended, name, value):
            return None
        try:
            return self.outputs(extended)
        except SimulationError:
            if value == 0.0:
                raise
            return None
