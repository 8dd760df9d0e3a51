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
multiple-shooting engine (:mod:`~torchpaml._simulate.shooting`). ``substeps="auto"`` (their default)
doubles the substeps until halving the step moves the output by at most ``rtol`` of its size
(:mod:`~torchpaml._simulate.step_control`); a number fixes them, unchecked. A fit returns the fixed
solver its step check resolved (``PhysicsEstimate.solver``), and the model simulates with it
(``physics.solver``).

Solvers are frozen values: compare them, print them, keep them in a config.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Literal

__all__ = ["Auto", "Dopri5", "Exact", "FixedStep", "RK4", "SEGMENT_STEPS", "Solver", "TRBDF2", "engine_solver", "inherited_solver"]

#: Default segment length L (steps) of the shooting engine. A sweep costs L dispatch-bound steps plus arithmetic
#: on every sample, which does not depend on L; 2 is the fastest of 1, 2, 4, 8 and 16 for simulations and
#: nonlinear fits from 600 to 65 536 samples (benchmarks/bench_simulation.py).
SEGMENT_STEPS = 2
#: Default ``rtol`` of the step doubling: the output's relative error, as scipy's ``solve_ivp`` defaults to.
STEP_RTOL = 1e-3


class Solver:
    """Base of the solvers (module docstring)."""


def _check_rtol(rtol: float) -> None:
    if not rtol > 0:
        raise ValueError(f"rtol must be positive, got {rtol}")


@dataclass(frozen=True)
class Exact(Solver):
    """The exact zero- or first-order-hold discretisation of linear physics on a uniform grid
    (:func:`~torchpaml._simulate.lti.simulate_lti`); raises ``ValueError`` for nonlinear physics."""

    #: One exact step per sample interval.
    substeps: ClassVar[int] = 1


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

    def __post_init__(self):
        m = self.substeps
        if m != "auto" and (isinstance(m, bool) or not isinstance(m, int) or m < 1):
            raise ValueError(f"substeps must be 'auto' (to rtol) or a whole number of steps per sample interval, at "
                             f"least 1; got {m!r}")
        if isinstance(self.segment, bool) or not isinstance(self.segment, int) or self.segment < 1:
            raise ValueError(f"segment must be a whole number of steps, at least 1; got {self.segment!r}")
        _check_rtol(self.rtol)

    def at(self, substeps: int) -> FixedStep:
        """This solver with ``substeps`` fixed."""
        return dataclasses.replace(self, substeps=substeps)


@dataclass(frozen=True)
class RK4(FixedStep):
    r"""Classical explicit RK4 (fourth order). Stable while $h\,|\lambda| \lesssim 2.8$ for every rate
    $\lambda$ of the physics, $h$ the substep."""

    order: ClassVar[int] = 4
    middle: ClassVar[float] = 0.5


#: TR-BDF2's split of a step: the trapezoid covers the first ``GAMMA`` of it, BDF2 the rest.
GAMMA = 2 - 2**0.5


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


@dataclass(frozen=True)
class Auto(Solver):
    """The default (module docstring): ``Exact`` where it applies, else ``RK4(rtol=rtol)``, else, where RK4 cannot
    reach ``rtol`` within its substeps, ``TRBDF2(rtol=rtol)``."""

    rtol: float = STEP_RTOL

    def __post_init__(self):
        _check_rtol(self.rtol)


def engine_solver(physics) -> FixedStep:
    """The fixed-step solver with which the shooting engine simulates ``physics`` where no solver is passed (the
    probes, the states of a fitted model): the model's own (``physics.solver``) where it is RK4 or TR-BDF2 at whole
    substeps, else RK4 at one substep per sample."""
    own = physics.solver
    return own if isinstance(own, FixedStep) and own.substeps != "auto" else RK4(substeps=1)


def inherited_solver(physics) -> FixedStep | None:
    """The solver of a model built on ``physics`` (``physics + effect``, a learned force, an injected rate): the
    fixed-step solver ``physics`` was fitted with, else ``None`` (``Auto()``; the exact path of a linear
    ``physics`` does not apply to the nonlinear model)."""
    own = physics.solver
    return own if isinstance(own, FixedStep) else None
