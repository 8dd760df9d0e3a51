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
built on it (whose step check then starts there) and to the probes of such a model (which simulate at its
resolution, exactly where the model is linear).

A solver owns every way of integrating: forward to its tolerance (:meth:`Solver.integrate`, what
:func:`~torchpaml.simulate` drives), the states at its current resolution (:meth:`Solver.states`), the output's
Jacobian in the parameters (:meth:`Solver.jacobian`, what fits use) and the step check's moves
(:meth:`Solver.refined`, :meth:`Solver.stable`, :meth:`Solver.fallback`). A new solver is one class: subclass
:class:`FixedStep` with a ``sweep`` (a one-step method in the parallel engine), or :class:`Solver` with ``integrate``
and ``states`` (its Jacobian then comes by central differences of its states). ``Auto`` is the only place where RK4
gives way to TR-BDF2. Solvers are frozen values: compare them, print them, keep them in a config.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar, Literal

import torch

from torchpaml._errors import ConfigurationError, ResolutionError, SimulationError
from torchpaml._grid import uniform_step
from torchpaml._simulate.blowup import BLOWUP, checked_output
from torchpaml._simulate.compiled_jacobian import compiled_jacobian
from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.fixed_step import simulate_fixed_step
from torchpaml._simulate.lti import exact_step, simulate_lti, simulate_lti_states
from torchpaml._simulate.ode import simulate_ode
from torchpaml._simulate.sensitivity import difference_jacobian, exact_jacobian, shooting_jacobian
from torchpaml._simulate.shooting import simulate_shooting
from torchpaml._simulate.step_control import MAX_SUBSTEPS, next_substeps
from torchpaml._simulate.steps import GAMMA, RK4_COEFFICIENTS, TRBDF2_COEFFICIENTS, rk4_sweep, trbdf2_sweep
from torchpaml._simulate.stiffness import RK4_STABILITY, STIFF_SUBSTEPS, stable_substeps
from torchpaml._simulate.warm import WarmStart

__all__ = ["Auto", "Dopri5", "Exact", "FixedStep", "RK4", "SEGMENT_STEPS", "Solver", "TRBDF2"]

#: Default segment length L (steps) of the shooting engine. A sweep costs L dispatch-bound steps plus arithmetic
#: on every sample, which does not depend on L; 2 is the fastest of 1, 2, 4, 8 and 16 for simulations and
#: nonlinear fits from 600 to 65 536 samples (benchmarks/bench_simulation.py).
SEGMENT_STEPS = 2
#: Default ``rtol`` of the step doubling: the output's relative error, as scipy's ``solve_ivp`` defaults to.
STEP_RTOL = 1e-3


class Solver(ABC):
    """Base of the solvers (module docstring): each integrates the physics by its own method.

    Attributes:
        substeps: steps per sample interval where the solver has a fixed step (``None``: adaptive, or a policy).
    """

    substeps = None
    #: $|h\lambda|$ up to which the solver's step is stable; ``None``: no limit (implicit, adaptive or exact).
    stability = None

    @abstractmethod
    def integrate(self, physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, *,
                  warm: WarmStart | None = None, hold: str = "foh", knots: torch.Tensor | None = None,
                  blowup: float = BLOWUP) -> torch.Tensor:
        """The output (batch, time, n_output) of ``physics`` from ``x0`` (batch, n_state) driven by ``u`` (batch,
        time, n_input) on the grid ``t`` (time,), to the solver's tolerance, checked against ``blowup`` (arguments
        of :func:`~torchpaml.simulate`, which checks them first)."""

    @abstractmethod
    def states(self, physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, *,
               warm: WarmStart | None = None, hold: str = "foh") -> torch.Tensor:
        """The states (batch, time, n_state) at the solver's current resolution, without a tolerance search: what a
        fit evaluates and a probe of a fitted model simulates. Differentiable when grad mode is on."""

    def jacobian(self, physics: Dynamics, raw: dict[str, torch.Tensor], t: torch.Tensor, u: torch.Tensor,
                 x0: torch.Tensor, *, warm: WarmStart | None = None, hold: str = "foh",
                 initial_state: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        """The output (batch, time, n_output) at :meth:`states`' resolution and its Jacobian (..., p [+ n_state]) in
        the raw parameters ``raw`` (:func:`~torchpaml._simulate.sensitivity.raw_parameters`), and in ``x0`` with
        ``initial_state`` (:func:`~torchpaml._simulate.simulator.output_jacobian`). Here by central differences of
        :meth:`states`; the built-in solvers override it with their own sensitivities."""
        return difference_jacobian(physics, raw, u, x0, initial_state,
                                   lambda x: self.states(physics, t, u, x, warm=warm, hold=hold))

    def stepping(self) -> FixedStep | None:
        """The fixed-step method this solver steps with, at its resolution (what ``Auto(start=solver)`` continues
        from); ``None`` for an exact or adaptive one."""
        return None

    def simulating(self, physics: Dynamics, t: torch.Tensor) -> Solver:
        """The solver that simulates ``physics`` on ``t`` at this one's resolution (what a fitted model reports as
        ``PhysicsEstimate.solver``): itself, unless it is a policy (``Auto``)."""
        return self

    def halved(self) -> Solver | None:
        """This solver at half its step (the step check's comparison, :mod:`~torchpaml._fit.resolution`); ``None``
        where it has no step to halve (an adaptive or exact solver: no step check)."""
        return None

    def refined(self, gap: float, target: float) -> Solver | None:
        """This solver at the finer step predicted to bring the step check's ``gap`` to ``target``; ``None`` where
        that is beyond :data:`~torchpaml._simulate.step_control.MAX_SUBSTEPS` or it has no step."""
        return None

    def stable(self, sigma: float, most: int = MAX_SUBSTEPS) -> Solver:
        """This solver at a step that is stable for the stiffness ``sigma``
        (:func:`~torchpaml._simulate.stiffness.stiffness`); itself where :attr:`stability` is ``None``. Raises
        :class:`~torchpaml.ResolutionError` beyond ``most`` substeps."""
        return self

    def fallback(self) -> Solver | None:
        """The solver to go on with where this one cannot resolve a fit (a :class:`~torchpaml.ResolutionError`);
        ``None``: the error stands. Only ``Auto`` has one: TR-BDF2 where its explicit method is too stiff."""
        return None


def _check_rtol(rtol: float) -> None:
    if not rtol > 0:
        raise ConfigurationError(f"rtol must be positive, got {rtol}")


@dataclass(frozen=True)
class Exact(Solver):
    """The exact zero- or first-order-hold discretisation of linear physics on a uniform grid
    (:func:`~torchpaml._simulate.lti.simulate_lti`); raises :class:`~torchpaml.ConfigurationError` for nonlinear
    physics."""

    #: One exact step per sample interval.
    substeps: ClassVar[int] = 1

    def _matrices(self, physics: Dynamics):
        matrices = physics.state_space()
        if matrices is None:
            raise ConfigurationError(f"solver=Exact() needs linear physics; {physics.display_name} is nonlinear. Use "
                                     "RK4()")
        return matrices

    def integrate(self, physics: Dynamics, t, u, x0, *, warm=None, hold="foh", knots=None, blowup=BLOWUP):
        return checked_output(simulate_lti(*self._matrices(physics), uniform_step(t), u, x0, hold), t, blowup)

    def states(self, physics: Dynamics, t, u, x0, *, warm=None, hold="foh"):
        A, B, _, _ = self._matrices(physics)
        return simulate_lti_states(A, B, uniform_step(t), u, x0, hold)

    def jacobian(self, physics: Dynamics, raw, t, u, x0, *, warm=None, hold="foh", initial_state=False):
        return exact_jacobian(physics, raw, t, u, x0, initial_state, hold)


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
    #: The method's compiled form (``"rk4"``, ``"trbdf2"``), which the engine runs in C from the physics' closed form
    #: (:mod:`~torchpaml._simulate.compiled`, :mod:`~torchpaml._simulate.compiled_jacobian`); ``None``: a new
    #: method, or a subclass with its own ``sweep``, steps by its ``sweep`` alone.
    compiles: ClassVar[str | None] = None

    def __init_subclass__(cls, **kwargs):
        """A subclass with its own ``sweep`` steps by it: it is not compiled unless it says so (``compiles``)."""
        super().__init_subclass__(**kwargs)
        if "sweep" in vars(cls) and "compiles" not in vars(cls):
            cls.compiles = None

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
    def sweep(self, physics: Dynamics, x: torch.Tensor, stages) -> torch.Tensor:
        """One step of the method per stage, for the rows of ``x`` (rows, n): the states at the step boundaries,
        (n, L + 1, rows) (:mod:`~torchpaml._simulate.steps`)."""

    @property
    def resolution(self) -> int:
        """The substeps :meth:`states` steps at: ``substeps``, one where they are ``"auto"``."""
        return 1 if self.substeps == "auto" else self.substeps

    def stepping(self) -> FixedStep:
        return self.at(self.resolution)

    def integrate(self, physics: Dynamics, t, u, x0, *, warm=None, hold="foh", knots=None, blowup=BLOWUP):
        return simulate_fixed_step(physics, t, u, x0, self, warm, hold, blowup)

    def states(self, physics: Dynamics, t, u, x0, *, warm=None, hold="foh"):
        return simulate_shooting(physics, t, u, x0, self.stepping(), warm, hold=hold)

    def jacobian(self, physics: Dynamics, raw, t, u, x0, *, warm=None, hold="foh", initial_state=False):
        compiled = compiled_jacobian(physics, raw, t, u, x0, self.stepping(), hold, initial_state)
        if compiled is not None:
            return compiled
        return shooting_jacobian(physics, raw, t, u, x0, self.stepping(), warm, initial_state, hold)

    def halved(self) -> FixedStep:
        return self.at(2 * self.resolution)

    def refined(self, gap: float, target: float) -> FixedStep | None:
        following = next_substeps(self.resolution, gap, target, self.order)
        return None if following > MAX_SUBSTEPS else self.at(following)

    def stable(self, sigma: float, most: int = MAX_SUBSTEPS) -> FixedStep:
        from_here = self.stepping()
        return from_here if self.stability is None else self.at(stable_substeps(from_here, sigma, most))


@dataclass(frozen=True)
class RK4(FixedStep):
    r"""Classical explicit RK4 (fourth order). Stable while $h\,|\lambda| \lesssim 2.8$ for every rate
    $\lambda$ of the physics, $h$ the substep."""

    order: ClassVar[int] = 4
    middle: ClassVar[float] = 0.5
    coefficients: ClassVar[tuple[float, ...]] = RK4_COEFFICIENTS
    stability: ClassVar[float | None] = RK4_STABILITY
    compiles: ClassVar[str | None] = "rk4"

    def sweep(self, physics: Dynamics, x, stages):
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
    compiles: ClassVar[str | None] = "trbdf2"

    def sweep(self, physics: Dynamics, x, stages):
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

    def integrate(self, physics: Dynamics, t, u, x0, *, warm=None, hold="foh", knots=None, blowup=BLOWUP):
        return checked_output(physics.output(self._states(physics, t, u, x0, hold, knots), u), t, blowup)

    def states(self, physics: Dynamics, t, u, x0, *, warm=None, hold="foh"):
        return self._states(physics, t, u, x0, hold, None)

    def _states(self, physics: Dynamics, t, u, x0, hold: str, knots: torch.Tensor | None) -> torch.Tensor:
        if hold == "zoh":
            raise ConfigurationError("hold='zoh' is simulated by the exact path and by the fixed-step solvers, not by "
                                     "Dopri5, whose interpolant is first-order; use solver=RK4() or the default")
        return simulate_ode(physics, t, u, x0, method="dopri5", rtol=self.rtol, atol=self.atol, adjoint=self.adjoint,
                            max_num_steps=self.max_num_steps, knots=knots)


@dataclass(frozen=True)
class Auto(Solver):
    """The default (module docstring): ``Exact`` where it applies, else the explicit method to ``rtol`` (``RK4``, or
    the method of ``start``), else, where it cannot reach ``rtol`` within
    :data:`~torchpaml._simulate.stiffness.STIFF_SUBSTEPS` substeps, ``TRBDF2(rtol=rtol)``.

    Attributes:
        rtol: the output's relative tolerance (the step doubling's).
        start: the solver a model was fitted with (a fit's ``PhysicsEstimate.solver``), which a model built on it
            continues from: where it is a fixed-step method (a :class:`FixedStep`: RK4, TR-BDF2, a user's own), its
            method and substeps are where the step doubling starts and the resolution of :meth:`states` and
            :meth:`jacobian`; otherwise (``None``, ``Exact()``) RK4 from one substep. It changes the work, not the
            result's tolerance.
    """

    rtol: float = STEP_RTOL
    start: Solver | None = None

    def __post_init__(self):
        _check_rtol(self.rtol)
        if self.start is not None and not isinstance(self.start, Solver):
            raise ConfigurationError(f"Auto's start is a solver (a fit's PhysicsEstimate.solver), got {self.start!r}")

    def stepping(self) -> FixedStep:
        """The fixed-step method and substeps the step doubling starts from: ``start``'s, else RK4 at one."""
        stepping = None if self.start is None else self.start.stepping()
        return RK4(substeps=1) if stepping is None else stepping

    def simulating(self, physics: Dynamics, t: torch.Tensor) -> Solver:
        return Exact() if exact_step(physics, t) is not None else self.stepping()

    def integrate(self, physics: Dynamics, t, u, x0, *, warm=None, hold="foh", knots=None, blowup=BLOWUP):
        if exact_step(physics, t) is not None:
            return Exact().integrate(physics, t, u, x0, hold=hold, blowup=blowup)
        method = self.stepping()
        tolerant = dataclasses.replace(method, substeps="auto", rtol=self.rtol)
        stiff = self.fallback()
        try:
            return simulate_fixed_step(physics, t, u, x0, tolerant, warm, hold, blowup,
                                       most_stable=MAX_SUBSTEPS if stiff is None else STIFF_SUBSTEPS,
                                       start=method.substeps)
        except (ResolutionError, SimulationError) as error:  # too stiff for the explicit step: the implicit method
            if stiff is None:
                raise
            try:
                implicit = dataclasses.replace(stiff.stepping(), substeps="auto", rtol=self.rtol)
                return simulate_fixed_step(physics, t, u, x0, implicit, WarmStart(), hold, blowup)
            except (ResolutionError, SimulationError):
                raise error from None

    def states(self, physics: Dynamics, t, u, x0, *, warm=None, hold="foh"):
        return self.simulating(physics, t).states(physics, t, u, x0, warm=warm, hold=hold)

    def jacobian(self, physics: Dynamics, raw, t, u, x0, *, warm=None, hold="foh", initial_state=False):
        return self.simulating(physics, t).jacobian(physics, raw, t, u, x0, warm=warm, hold=hold,
                                                    initial_state=initial_state)

    @property
    def stability(self) -> float | None:
        return self.stepping().stability

    def halved(self) -> Auto:
        return dataclasses.replace(self, start=self.stepping().halved())

    def refined(self, gap: float, target: float) -> Auto | None:
        finer = self.stepping().refined(gap, target)
        return None if finer is None else dataclasses.replace(self, start=finer)

    def stable(self, sigma: float, most: int = MAX_SUBSTEPS) -> Auto:
        return dataclasses.replace(self, start=self.stepping().stable(sigma, most))

    def fallback(self) -> Auto | None:
        method = self.stepping()
        if method.stability is None:  # already implicit
            return None
        return dataclasses.replace(self, start=TRBDF2(substeps=1, segment=method.segment))
