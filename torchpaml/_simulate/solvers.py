r"""The simulator's solvers: objects that say how :func:`~torchpaml.simulate` integrates, passed in as ``solver=``.

========================  ==========================================================================
``Auto(rtol)`` (default)  exact for linear physics on a uniform grid; otherwise ``RK4`` to ``rtol``, and
                          where RK4 cannot reach it (a rate far faster than the sampling: stiff
                          physics), ``TRBDF2`` to ``rtol``
``Exact()``               the exact discretisation of linear physics (``state_space()``), uniform grid
``RK4(substeps, rtol)``   classical RK4, explicit, fourth order, parallel in time
``TRBDF2(substeps, rtol)`` TR-BDF2, implicit and L-stable, second order, parallel in time: stiff physics
``Dopri5(rtol, atol)``    torchdiffeq's adaptive Dormand-Prince, with per-step error control
========================  ==========================================================================

``RK4`` and ``TRBDF2`` step on the sample grid, ``substeps`` steps per sample interval, in the
multiple-shooting engine (:mod:`~torchpaml._simulate.shooting`), each by its own :meth:`~FixedStep.sweep`.
``substeps="auto"`` (their default) doubles the substeps until halving the step moves the output by at most
``rtol`` of its size (:mod:`~torchpaml._simulate.step_control`); a number fixes them, unchecked. A fit returns the
fixed solver its step check resolved (``PhysicsEstimate.solver``); pass it on to simulate the fitted model as it
was fitted (``simulate(physics, t, u, solver=fit.solver)``), or as ``Auto(start=fit.solver)`` to a fit of a model
built on it, whose step check then starts there.

Each solver integrates (:meth:`Solver.integrate`); :func:`~torchpaml.simulate` checks the arguments and the output
and only drives it. Solvers are frozen values: compare them, print them, keep them in a config.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar, Literal

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._errors import ConfigurationError, ResolutionError, SimulationError
from torchpaml._grid import uniform_step
from torchpaml._simulate.blowup import checked_output
from torchpaml._simulate.fixed_step import simulate_fixed_step
from torchpaml._simulate.lti import exact_step, simulate_lti
from torchpaml._simulate.ode import simulate_ode
from torchpaml._simulate.steps import GAMMA, RK4_COEFFICIENTS, TRBDF2_COEFFICIENTS, rk4_sweep, trbdf2_sweep
from torchpaml._simulate.stiffness import RK4_STABILITY, STIFF_SUBSTEPS
from torchpaml._simulate.warm import WarmStart

__all__ = ["Auto", "Dopri5", "Exact", "FixedStep", "RK4", "SEGMENT_STEPS", "Solver", "TRBDF2", "continued",
           "engine_solver"]

#: Default segment length L (steps) of the shooting engine. A sweep costs L dispatch-bound steps plus arithmetic
#: on every sample, which does not depend on L; 2 is the fastest of 1, 2, 4, 8 and 16 for simulations and
#: nonlinear fits from 600 to 65 536 samples (benchmarks/bench_simulation.py).
SEGMENT_STEPS = 2
#: Default ``rtol`` of the step doubling: the output's relative error, as scipy's ``solve_ivp`` defaults to.
STEP_RTOL = 1e-3


class Solver(ABC):
    """Base of the solvers (module docstring): each integrates the physics by its own method."""

    @abstractmethod
    def integrate(self, physics: AbstractPhysics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, *,
                  warm: WarmStart | None,
                  hold: str, knots: torch.Tensor | None, blowup: float) -> torch.Tensor:
        """The output (batch, time, n_output) of ``physics`` from ``x0`` (batch, n_state) driven by ``u`` (batch,
        time, n_input) on the grid ``t`` (time,), checked against ``blowup`` (arguments of
        :func:`~torchpaml.simulate`, which checks them first)."""


def _check_rtol(rtol: float) -> None:
    if not rtol > 0:
        raise ConfigurationError(f"rtol must be positive, got {rtol}")


@dataclass(frozen=True)
class Exact(Solver):
    """The exact zero- or first-order-hold discretisation of linear physics on a uniform grid
    (:func:`~torchpaml._simulate.lti.simulate_lti`); raises ``ValueError`` for nonlinear physics."""

    #: One exact step per sample interval.
    substeps: ClassVar[int] = 1

    def integrate(self, physics: AbstractPhysics, t, u, x0, *, warm, hold, knots, blowup):
        matrices = physics.state_space()
        if matrices is None:
            raise ConfigurationError(f"solver=Exact() needs linear physics; {physics.display_name} is nonlinear. Use RK4()")
        return checked_output(simulate_lti(*matrices, uniform_step(t), u, x0, hold), t, blowup)


@dataclass(frozen=True)
class FixedStep(Solver):
    """A one-step method on the sample grid, in the parallel-in-time shooting engine.

    Attributes:
        substeps: steps per sample interval, or ``"auto"``: doubled until halving the step moves the output
            by at most ``rtol`` of its size (:func:`~torchpaml._simulate.step_control.simulate_to_tolerance`).
        rtol: the relative tolerance of ``substeps="auto"``.
        segment: steps per shooting segment (:data:`SEGMENT_STEPS`).
    """

    substeps: int | Literal["auto"] = "auto"
    rtol: float = STEP_RTOL
    segment: int = SEGMENT_STEPS
    #: The method's order of accuracy (the step doubling's error model).
    order: ClassVar[int]
    #: The fraction of a step at which the method evaluates its middle stage.
    middle: ClassVar[float]
    #: The method's step coefficients, as multiples of the substep (:mod:`~torchpaml._simulate.steps`).
    coefficients: ClassVar[tuple[float, ...]]
    #: $|h\lambda|$ up to which the method is stable, ``None`` for an implicit, L-stable one
    #: (:mod:`~torchpaml._simulate.stiffness`).
    stability: ClassVar[float | None]

    def __post_init__(self):
        m = self.substeps
        if m != "auto" and (isinstance(m, bool) or not isinstance(m, int) or m < 1):
            raise ConfigurationError(f"substeps must be 'auto' (to rtol) or a whole number of steps per sample interval, at "
                             f"least 1; got {m!r}")
        if isinstance(self.segment, bool) or not isinstance(self.segment, int) or self.segment < 1:
            raise ConfigurationError(f"segment must be a whole number of steps, at least 1; got {self.segment!r}")
        _check_rtol(self.rtol)

    def at(self, substeps: int) -> FixedStep:
        """This solver with ``substeps`` fixed."""
        return dataclasses.replace(self, substeps=substeps)

    @abstractmethod
    def sweep(self, physics: AbstractPhysics, x: torch.Tensor, stages) -> torch.Tensor:
        """One step of the method per stage, for the rows of ``x`` (rows, n): the states at the step boundaries,
        (n, L + 1, rows) (:mod:`~torchpaml._simulate.steps`)."""

    def integrate(self, physics: AbstractPhysics, t, u, x0, *, warm, hold, knots, blowup):
        return simulate_fixed_step(physics, t, u, x0, self, warm, hold, blowup)


@dataclass(frozen=True)
class RK4(FixedStep):
    r"""Classical explicit RK4 (fourth order). Stable while $h\,|\lambda| \lesssim 2.8$ for every rate
    $\lambda$ of the physics, $h$ the substep."""

    order: ClassVar[int] = 4
    middle: ClassVar[float] = 0.5
    coefficients: ClassVar[tuple[float, ...]] = RK4_COEFFICIENTS
    stability: ClassVar[float | None] = RK4_STABILITY

    def sweep(self, physics: AbstractPhysics, x, stages):
        return rk4_sweep(physics, x, stages, self.substeps)


@dataclass(frozen=True)
class TRBDF2(FixedStep):
    r"""TR-BDF2 (Bank et al. 1985; MATLAB's ``ode23tb``): implicit, L-stable, second order.

    A step of length $h$ is a trapezoid step to $t + \gamma h$ and a BDF2 step on $t,\ t+\gamma h,\ t+h$,
    with $\gamma = 2 - \sqrt 2$:

    $$ x_\gamma = x + \tfrac{\gamma h}{2}\,\bigl(f(x) + f(x_\gamma)\bigr), \qquad
       x_1 = \frac{x_\gamma - (1-\gamma)^2 x}{\gamma(2-\gamma)} + \frac{1-\gamma}{2-\gamma}\,h\,f(x_1). $$

    Both stages solve $z = a + d\,h\,f(z)$ with the same $d = 1 - 1/\sqrt 2$, by Newton's method.
    L-stable: a rate far faster than the step is damped, not amplified, so stiff physics (a spill
    that empties in a fraction of a sample interval) is integrated at one step per sample.
    """

    order: ClassVar[int] = 2
    middle: ClassVar[float] = GAMMA
    coefficients: ClassVar[tuple[float, ...]] = TRBDF2_COEFFICIENTS
    stability: ClassVar[float | None] = None

    def sweep(self, physics: AbstractPhysics, x, stages):
        return trbdf2_sweep(physics, x, stages, self.substeps)


@dataclass(frozen=True)
class Dopri5(Solver):
    """torchdiffeq's adaptive Dormand-Prince 5(4) (:func:`~torchpaml._simulate.ode.simulate_ode`).

    Attributes:
        rtol, atol: per-step tolerances.
        adjoint: differentiate by the adjoint method.
        max_num_steps: step limit.
    """

    rtol: float = 1e-7
    atol: float = 1e-9
    adjoint: bool = False
    max_num_steps: int = 1_000_000

    def __post_init__(self):
        _check_rtol(self.rtol)

    def integrate(self, physics: AbstractPhysics, t, u, x0, *, warm, hold, knots, blowup):
        if hold == "zoh":
            raise ConfigurationError("hold='zoh' is simulated by the exact path and by the fixed-step solvers, not by Dopri5, "
                             "whose interpolant is first-order; use solver=RK4() or the default")
        states = simulate_ode(physics, t, u, x0, method="dopri5", rtol=self.rtol, atol=self.atol,
                              adjoint=self.adjoint, max_num_steps=self.max_num_steps, knots=knots)
        return checked_output(physics.output(states, u), t, blowup)


@dataclass(frozen=True)
class Auto(Solver):
    """The default (module docstring): ``Exact`` where it applies, else ``RK4(rtol=rtol)``, else, where RK4 cannot
    reach ``rtol`` within :data:`~torchpaml._simulate.stiffness.STIFF_SUBSTEPS` substeps, ``TRBDF2(rtol=rtol)``.

    Attributes:
        rtol: the output's relative tolerance (the step doubling's).
        start: a fixed-step solver whose substeps the step doubling of the same method starts from (a previous
            fit's ``PhysicsEstimate.solver``, :func:`continued`); it changes the work, not the result's tolerance.
    """

    rtol: float = STEP_RTOL
    start: FixedStep | None = None

    def __post_init__(self):
        _check_rtol(self.rtol)

    def _start(self, method: FixedStep) -> int:
        own = self.start
        return own.substeps if type(own) is type(method) and own.substeps != "auto" else 1

    def integrate(self, physics: AbstractPhysics, t, u, x0, *, warm, hold, knots, blowup):
        if exact_step(physics, t) is not None:
            return Exact().integrate(physics, t, u, x0, warm=warm, hold=hold, knots=knots, blowup=blowup)
        explicit, implicit = RK4(rtol=self.rtol), TRBDF2(rtol=self.rtol)
        try:
            return simulate_fixed_step(physics, t, u, x0, explicit, warm, hold, blowup, most_stable=STIFF_SUBSTEPS,
                                       start=self._start(explicit))
        except (ResolutionError, SimulationError) as error:  # too stiff for RK4's step: the implicit method
            try:
                return simulate_fixed_step(physics, t, u, x0, implicit, WarmStart(), hold, blowup,
                                           start=self._start(implicit))
            except (ResolutionError, SimulationError):
                raise error from None


def engine_solver(solver: Solver | None) -> FixedStep:
    """The fixed-step solver with which the shooting engine simulates a model where ``solver`` says how it was
    fitted (the probes, the states of a fitted model): ``solver`` where it is RK4 or TR-BDF2 at whole substeps, an
    ``Auto``'s ``start``, else RK4 at one substep per sample."""
    if isinstance(solver, Auto):
        solver = solver.start
    return solver if isinstance(solver, FixedStep) and solver.substeps != "auto" else RK4(substeps=1)


def continued(solver: Solver | None) -> Auto:
    """The solver of a fit of a model built on one fitted with ``solver`` (``physics + effect``, a learned force, a
    freed shape): the default ``Auto()``, its step check started from ``solver`` where that is a fixed-step one (the
    exact path of a linear physics does not apply to the nonlinear model)."""
    if isinstance(solver, Auto):
        return solver
    return Auto(start=solver if isinstance(solver, FixedStep) else None)
