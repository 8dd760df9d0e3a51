r"""The step check: a fitted model's output must not depend on the solver's step.

The shooting engine advances each sample interval $h$ in $m$ steps of the fit's solver (RK4 or
TR-BDF2). After a fit, the records are simulated again at $2m$; the gap

$$ g = \frac{\|\hat y_m - \hat y_{2m}\|}{\|y\|} $$

estimates the discretisation error of $\hat y_m$ (a method of order $p$: that error is
$g / (1 - 2^{-p})$ where the solution is smooth, $\tfrac{16}{15}g$ for RK4). The fit stands when $g \le$ :data:`STEP_TOLERANCE` $\cdot\,\|r\|$, with
$\|r\| = \|y - \hat y\|/\|y\|$ the misfit, or when $g \le$ :data:`STEP_FLOOR` (a noiseless record fitted
exactly): the step then moves a printed mismatch by a tenth of it at most. Otherwise $m$ grows by the
power of two that fourth order predicts brings $g$ to half the tolerance
(:func:`~torchpaml._simulate.step_control.next_substeps`, the rule :func:`~torchpaml.simulate`'s own step
doubling follows), and the fit goes on from its optimum at the finer step, until the check passes.

Beyond :data:`MAX_SUBSTEPS` it raises :class:`~torchpaml.ResolutionError`: a rate of the fitted
model is far faster than the sampling (a spill at 40 1/s in a record sampled every 4 s), and the fit
settles where RK4's error, not the physics, explains the data. :func:`~torchpaml.fit_physics` with
its default solver then goes on with the implicit TR-BDF2, which integrates such a rate at one step per
sample; with a solver the user chose it raises. Records on the exact path (linear physics on a uniform
grid) have no step error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from torchpaml._physics.base import AbstractPhysics
from torchpaml._data import Record
from torchpaml._errors import ResolutionError, SimulationError
from torchpaml._data.simulation import record_states
from torchpaml._simulate.blowup import checked_output
from torchpaml._simulate.solvers import TRBDF2, Solver
from torchpaml._simulate.step_control import MAX_SUBSTEPS
from torchpaml._simulate.stiffness import stiffness

__all__ = ["MAX_SUBSTEPS", "STEP_FLOOR", "STEP_TOLERANCE", "resolved_solver", "stable_solver", "step_gap"]

STEP_TOLERANCE = 0.1
STEP_FLOOR = 1e-6
#: Samples per step of the stability probe's TR-BDF2 trajectory.
PROBE_STRIDE = 16


def _output(physics: AbstractPhysics, record: Record, x0: torch.Tensor | None, solver: Solver) -> torch.Tensor:
    """The output (time, n_output) on ``record`` at ``solver``'s resolution (:meth:`~torchpaml.Solver.states`)."""
    start = physics.initial_state(1) if x0 is None else x0.reshape(1, -1)
    t, u = record.elapsed, record.u[None]
    with torch.no_grad():
        return checked_output(physics.output(solver.states(physics, t, u, start, hold=record.hold), u), t)[0]


def step_gap(physics: AbstractPhysics, solver: Solver, records: Sequence[Record],
             states: Sequence[torch.Tensor | None],
             outputs: Sequence[torch.Tensor] | None = None) -> float:
    """$g$ (module docstring) of ``solver`` over the records where it has a step to halve
    (:meth:`~torchpaml.Solver.halved`: not on the exact path), from each record's initial state (or rest); 0 where
    none has. ``outputs``: each record's output at ``solver`` (time, n_output) where the caller has it (a fit's last
    evaluation), else simulated here."""
    squared, norm = 0.0, 0.0
    for i, (record, x0) in enumerate(zip(records, states, strict=True)):
        at = solver.simulating(physics, record.elapsed)
        finer = at.halved()
        if finer is None:
            continue
        coarse = _output(physics, record, x0, at) if outputs is None else outputs[i]
        squared += float((coarse - _output(physics, record, x0, finer)).square().sum())
        norm += float(record.y.square().sum())
    return 0.0 if norm == 0.0 else math.sqrt(squared / norm)


def _stiffness(physics: AbstractPhysics, record: Record, x0: torch.Tensor | None, solver: Solver) -> float:
    r"""$\sigma$ of ``record`` (:func:`~torchpaml._simulate.stiffness.stiffness`) along the trajectory that the
    L-stable TR-BDF2 draws at one step per :data:`PROBE_STRIDE` samples: it follows the physics into a stiff region
    that an unstable explicit step can leave unseen, at a fraction of a simulation's cost; along ``solver``'s own
    trajectory where TR-BDF2's Newton does not converge (a corner it cannot resolve at that step)."""
    coarse = Record(record.t[::PROBE_STRIDE], record.u[::PROBE_STRIDE], record.y[::PROBE_STRIDE], record.name,
                    hold=record.hold)
    try:
        states, probe, stride = record_states(physics, coarse, x0, TRBDF2(substeps=1)), coarse, PROBE_STRIDE
    except SimulationError:
        states, probe, stride = record_states(physics, record, x0, solver), record, 1
    return stiffness(physics, probe.elapsed, probe.u[None], states[None]) / stride


def stable_solver(physics: AbstractPhysics, solver: Solver, records: Sequence[Record],
                  states: Sequence[torch.Tensor | None],
                  most_stable: int = MAX_SUBSTEPS) -> Solver:
    """``solver`` at the step where it is stable along the trajectory of ``physics``
    (:meth:`~torchpaml.Solver.stable`): itself where its step has no stability limit, or where every record takes
    the exact path. Raises :class:`~torchpaml.ResolutionError` where that needs more than ``most_stable``."""
    if solver.stability is None:
        return solver
    sigma = max((_stiffness(physics, r, x0, solver) for r, x0 in zip(records, states, strict=True)
                 if solver.simulating(physics, r.elapsed).stability is not None), default=0.0)
    return solver.stable(sigma, most_stable)


def resolved_solver(physics: AbstractPhysics, solver: Solver, records: Sequence[Record],
                    states: Sequence[torch.Tensor | None],
                    misfit: float, most_stable: int = MAX_SUBSTEPS, outputs: Sequence[torch.Tensor] | None = None
                    ) -> Solver:
    """The solver at the step where the fitted ``physics`` passes the step check (module docstring): ``solver``
    where it passes; else, where its explicit step is unstable along the fitted trajectory, it at the step that
    makes it stable (:func:`stable_solver`); else it at the finer step its order predicts to pass
    (:meth:`~torchpaml.Solver.refined`). ``outputs``: each record's output at ``solver`` where the caller has it
    (:func:`step_gap`). Raises :class:`~torchpaml.ResolutionError` beyond :data:`MAX_SUBSTEPS`, or where stability
    alone needs more than ``most_stable``."""
    stable = stable_solver(physics, solver, records, states, most_stable)
    if stable != solver:  # the step doubling cannot judge an unstable step
        return stable
    gap = step_gap(physics, solver, records, states, outputs)
    allowed = STEP_TOLERANCE * misfit
    if gap <= max(allowed, STEP_FLOOR):
        return solver
    following = solver.refined(gap, max(allowed, STEP_FLOOR))
    if following is None:
        step = float(records[0].t[1] - records[0].t[0])
        method = solver.stepping() or solver
        raise ResolutionError(
            f"{physics.display_name}'s fitted output depends on the {type(method).__name__} step: halving the step at "
            f"{method.substeps} substeps per sample moves it by {100 * gap:.3g} % of the output, against a misfit of "
            f"{100 * misfit:.3g} %, and resolving it needs more than {MAX_SUBSTEPS} substeps. A rate of the fitted model is far faster than the sampling (h = {step:g} "
            f"s), and the fit settled where the integration error explains the data. Fit with solver=TRBDF2() "
            f"(implicit, for stiff physics), bound that rate (physics.bound(name, lower, upper)) to what the sampling "
            f"resolves, or sample faster. Parameters: {physics.physical_parameters()}")
    return following
