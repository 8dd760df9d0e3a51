r"""The one physics fit: output error by a trust-region method, with forward-mode Jacobians.

$$ \hat\rho = \arg\min_\rho \tfrac12 \|r(\rho)\|^2, \qquad r = \frac{y - \mathcal H^{\theta(\rho)}[u]}{\|y\|} $$

over the raw (unconstrained) values $\rho$ of the learnable physical parameters $\theta$, all records
stacked. ``scipy.optimize.least_squares`` (``method="trf"``) solves it; its Jacobian
$\partial r/\partial\rho$ comes from :func:`~torchpaml.output_jacobian` (exact path for linear
physics, the parallel RK4 engine otherwise: one Newton solve and one sweep per parameter).

**Bounds** are the one bound mechanism: ``bounds={name: (lower, upper)}`` in physical units become
closed bounds on $\rho$ through the parameter's own constraint map (monotone, so the interval maps to
an interval), and the trust region keeps every iterate strictly inside. An optimum beyond a bound ends on it:
where the unknowns that press on their bounds, set on them, cost no more (to 1e-9), they are held there and the
others fitted again (:func:`_settled_on_bounds`; the paper's $\zeta$ capped at 5 for $\alpha = 10$).

The estimate carries its :class:`~torchpaml._fit.uncertainty.Uncertainty` (standard errors, 95 %
intervals, identifiability; ``physics.describe(estimate.uncertainty)`` prints them); an
:class:`~torchpaml._fit.uncertainty.IdentifiabilityWarning` names a combination the records do not determine.

Trial steps whose simulation blows up are rejected by the trust region (their residual is inf);
a start that blows up raises :class:`~torchpaml.SimulationError`.

**One arithmetic path** (:mod:`torchpaml._fit.one_thread`): the fit runs on one thread, so that its numbers do not
depend on the machine's cores.

**The step check** (:mod:`torchpaml._fit.resolution`): at the optimum the output must not depend on the
solver's step; where it does, the substeps grow and the fit goes on from the optimum. With the default
solver, an optimum that RK4 cannot resolve (stiff physics) goes on with the implicit TR-BDF2. The fit
returns the solver it resolved (``PhysicsEstimate.solver``). It writes the fitted values into the parameters of
``physics`` and nothing else: no attribute of the module changes.
"""

from __future__ import annotations

import contextlib
import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from scipy.optimize import least_squares

from torchpaml._budget import Budget
from torchpaml._data import Record
from torchpaml._errors import ConfigurationError, ResolutionError
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._fit.initial_state import Estimate, InitialState, Rest, as_initial_state
from torchpaml._fit.one_thread import one_thread
from torchpaml._fit.resolution import MAX_SUBSTEPS, resolved_solver, stable_solver
from torchpaml._fit.trust_region import TrustRegionProblem
from torchpaml._fit.uncertainty import Uncertainty, constraint_slopes, parameter_uncertainty, warn_if_unidentifiable
from torchpaml._parameters import raw_limits
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.checks import check_channels
from torchpaml._data.checks import check_outputs_vary
from torchpaml._simulate.simulator import checked_solver
from torchpaml._simulate.solvers import Exact, Solver
from torchpaml._simulate.stiffness import STIFF_SUBSTEPS
from torchpaml._simulate.warm import WarmStart

__all__ = ["PhysicsEstimate", "estimate_initial_state", "fit_physics"]


@dataclass
class PhysicsEstimate:
    """Result of :func:`fit_physics`.

    Attributes:
        parameters: fitted learnable parameters in physical units.
        mismatch: $\\|y - \\hat y\\| / \\|y\\|$ over all records (a fraction).
        residual: $r = (y - \\hat y)/\\|y\\|$ at the optimum, all records concatenated, (samples,).
        jacobian: $\\partial r / \\partial\\rho$ at the optimum, (samples, unknowns): the columns of ``parameters``
            in their order, then each record's initial state where it was estimated.
        evaluations: number of simulations (a Jacobian counts as one).
        uncertainty: standard errors, 95 % intervals and the identifiability check of ``parameters``
            (and of the initial states, named ``x0[record].state``, where they were estimated).
        initial_states: each record's initial state (n_state,): rest, or the estimate.
        physics: the physics fitted (the module itself, its parameters at the optimum).
        solver: the solver the fit ended with (the step check; :meth:`~torchpaml.Solver.simulating`): a fixed-step
            method at whole substeps, or ``Exact()`` where every record takes the exact path. Simulate the fitted
            model with it to simulate it as the fit did; fit a model built on this one with ``Auto(start=solver)`` to
            start its step check here.
    """

    parameters: dict[str, float]
    mismatch: float
    residual: torch.Tensor
    jacobian: torch.Tensor
    evaluations: int
    uncertainty: Uncertainty
    initial_states: list[torch.Tensor]
    solver: Solver
    physics: AbstractPhysics | None = field(default=None, repr=False)

    @property
    def model(self) -> FittedModel:
        """The fitted physics with its solver and the fit's uncertainty, one value that simulates a record as the fit
        did (``fit.model.simulate(record, fit.initial_states[i])``) and that :func:`~torchpaml.save_model` writes."""
        return FittedModel(self.physics, self.solver, uncertainty=self.uncertainty)


def _raw_bounds(physics: AbstractPhysics, names: list[str], bounds: dict[str, tuple[float,
                float]]) -> tuple[np.ndarray, np.ndarray]:
    lower, upper = np.full(len(names), -np.inf), np.full(len(names), np.inf)
    unknown = sorted(set(bounds) - set(names))
    if unknown:
        raise ConfigurationError(f"bounds name parameter(s) {unknown} that are not learnable; learnable: {names}")
    for i, name in enumerate(names):
        if name not in bounds:
            continue
        lo, hi = (float(b) for b in bounds[name])
        if not lo < hi:
            raise ConfigurationError(f"bounds for {name!r} need lower < upper, got ({lo}, {hi})")
        owner, leaf = physics._owner(name)
        constraint = getattr(owner.parametrizations, leaf)[0]
        value = float(getattr(owner, leaf).detach())
        if not lo <= value <= hi:
            raise ConfigurationError(f"{name} = {value:g} starts outside its bounds ({lo:g}, {hi:g}); assign a start inside")
        with torch.no_grad():
            ends = constraint.right_inverse(torch.tensor([lo, hi], dtype=torch.float64)).nan_to_num(-np.inf, np.inf, -np.inf)
        lower[i], upper[i] = float(ends[0]), float(ends[1])
    return lower, upper


def _held_in(x: np.ndarray, limits: list[float], lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The start ``x`` with each raw parameter beyond its limit (:func:`~torchpaml._parameters.raw_limits`) brought
    to it, within the bounds: a saturated parameter starts where its map is at its limit to 4e-18, not at a raw
    value that an earlier fit left anywhere beyond."""
    x = x.copy()
    for i, limit in enumerate(limits):
        if abs(x[i]) > limit:
            x[i] = float(np.clip(math.copysign(limit, x[i]), lower[i], upper[i]))
    return x


def fit_physics(
    physics: AbstractPhysics,
    records: Record | Sequence[Record],
    *,
    bounds: dict[str, tuple[float, float]] | None = None,
    initial_state: str | InitialState = Rest(),
    start_states: Sequence[torch.Tensor] | None = None,
    warm: Sequence[WarmStart] | None = None,
    max_nfev: int = 60,
    ftol: float = 1e-10,
    solver: Solver | None = None,
    budget: Budget | None = None,
) -> PhysicsEstimate:
    r"""Fit the learnable physical parameters of ``physics`` in place to the records (module docstring).

    Args:
        physics: the model; its learnable parameters are fitted, the others stay fixed. With
            ``Estimate()`` it may have none (then only the initial states are fitted).
        records: one or more :class:`~torchpaml.Record`.
        bounds: ``{name: (lower, upper)}`` in physical units.
        initial_state: ``Rest()`` (each record starts at rest; or ``"rest"``) or ``Estimate()`` (``"estimate"``:
            each record's initial state is fitted too, an unbounded unknown per state; see
            ``PhysicsEstimate.initial_states``; :mod:`~torchpaml._fit.initial_state`).
        start_states: with ``Estimate()``, each record's starting guess (n_state,), or of
            the base's states of ``physics + effect`` (:func:`~torchpaml.complete_state`) (default: rest).
        warm: one :class:`~torchpaml.WarmStart` per record that carries the RK4 engine's last solution into the
            fit's first Newton solve (``simulate(..., warm=)``, e.g. of a simulation at the start); default fresh ones.
        max_nfev: iteration limit of the trust region; where unknowns press on their bounds at the end, up to
            :data:`SETTLING` more to fit the others with those held on the bounds (:func:`_settled_on_bounds`).
        ftol: the trust region stops when a step lowers the cost $\tfrac12\|r\|^2$ by less than this share of it
            (scipy's ``ftol``); the default fits to the last digits, a ranking's refits stop earlier.
        solver: any :class:`~torchpaml.Solver`, at whose resolution (:meth:`~torchpaml.Solver.states`) the fit
            simulates and differentiates: ``RK4(...)``, ``TRBDF2(...)`` or a user's fixed-step method, from its
            substeps (``"auto"``: one); ``Auto()``/``None`` (the default): the exact path for linear physics, else RK4
            at one substep (or from ``Auto``'s ``start``, a previous fit's solver), and TR-BDF2 where RK4 cannot
            resolve the optimum (:meth:`~torchpaml.Solver.fallback`); an adaptive one (``Dopri5()``) as it is. The
            step check refines the step where the fitted output depends on it (:mod:`torchpaml._fit.resolution`).
        budget: a :class:`~torchpaml.Budget`: progress lines while the fit runs, and
            :class:`~torchpaml.OverBudget` raised past its limit (default: neither).
    """
    initial_state = as_initial_state(initial_state)
    records = [records] if isinstance(records, Record) else list(records)
    names = _checked_unknowns(physics, records, initial_state, start_states)
    problem = TrustRegionProblem(physics, records, names, initial_state, checked_solver(solver),
                                 [WarmStart() for _ in records] if warm is None else list(warm), budget)
    lower, upper = _raw_bounds(physics, names, bounds or {})
    states = initial_state.unknowns(physics, records)  # unbounded
    lower, upper = np.concatenate([lower, np.full(states, -np.inf)]), np.concatenate([upper, np.full(states, np.inf)])
    x = _held_in(problem.start(start_states, lower, upper), raw_limits(physics, names), lower, upper)
    problem.evaluate(x)  # raises SimulationError, naming the blow-up, at a bad start
    step_check = _StepCheck(problem)
    result = None
    with one_thread(), budget.active() if budget is not None else contextlib.nullcontext():  # the step check's too
        while (resolved := step_check.solver(x, result is not None)) != problem.solver or result is None:
            problem.use(resolved)  # at the start, then at each optimum
            result = _restarted(problem, x, (lower, upper), max_nfev, ftol)
            x = result.x
    return _estimate(problem, result.x)


#: How scipy's ``least_squares`` ended where a restart may go on: the change of the cost (``ftol``), of the unknowns
#: (``xtol``), or both; not the gradient (``gtol``), not the evaluation limit.
_STALLED = (2, 3, 4)


def _restarted(problem: TrustRegionProblem, x: np.ndarray, bounds: tuple, max_nfev: int, ftol: float):
    r"""``least_squares`` (trf) from ``x``, restarted from where it stopped while a restart lowers the cost by more
    than ``ftol`` of it; at most ``max_nfev`` evaluations in all.

    trf stops where one step lowers the cost by less than ``ftol`` of it (or moves the unknowns by less than
    ``xtol``). In a curved valley its trust region shrinks to short steps, and it stops there far from the optimum:
    a ranking's refit on the cascaded tanks (``ftol`` = 0.1/n) stopped at 6.12 % on training, and a restart from that
    point, whose trust region starts afresh, went on to 4.65 %. Where the fit is at its optimum, the restart's
    first step gains less than ``ftol`` and it ends: one iteration more.
    """
    result = _trf(problem, x, bounds, max_nfev, ftol)
    left = max_nfev - result.nfev
    while result.status in _STALLED and left > 0:
        again = _trf(problem, result.x, bounds, left, ftol)
        left -= again.nfev
        went_on = again.cost < (1.0 - ftol) * result.cost
        if again.cost <= result.cost:
            result = again
        if not went_on:
            break
    return _settled_on_bounds(problem, result, bounds, left, ftol)


def _trf(problem: TrustRegionProblem, start: np.ndarray, bounds: tuple, evaluations: int, ftol: float):
    """One run of scipy's ``least_squares`` (trf) on ``problem`` from ``start``, within ``bounds`` and
    ``evaluations``."""
    return least_squares(problem.residual, start, jac=lambda x: problem.evaluate(x)[1], bounds=bounds, method="trf",
                         x_scale="jac", max_nfev=evaluations, ftol=ftol, xtol=1e-10, gtol=1e-10)


#: Where holding the unknowns that press on their bounds exactly on them changes the cost by no more than this share
#: of it, the optimum is on the bounds (:func:`_settled_on_bounds`).
ON_BOUND = 1e-9
#: The width, relative to ``max(1, |bound|)``, of the interval an unknown held on its bound keeps.
HELD_WIDTH = 1e-12
#: The evaluations the fit of the others may take once unknowns are held on their bounds, where the fit has fewer
#: left: a fit that crawled towards a bound often ends at its evaluation limit.
SETTLING = 20


def _settled_on_bounds(problem: TrustRegionProblem, result, bounds: tuple, left: int, ftol: float):
    r"""Where the optimum lies on bounds, the fit ended exactly on them.

    trf keeps its iterates strictly inside the bounds, so an unknown whose optimum lies beyond its bound crawls towards
    it, and the fit stops wherever a step first gains less than ``ftol``: on EMPS's Coulomb friction, 1.1e-4 and
    3.3e-4 (raw, relative) short of the bound on two copies of the records that differ by 1e-12, and the other
    parameters' optimum, and every figure, moved with that gap (2.4e-5 on validation). Each bounded unknown whose
    gradient $J^\top r$ presses on its bound is set on it; if that changes the cost by at most :data:`ON_BOUND` of it,
    they are held there (in an interval of :data:`HELD_WIDTH`) and the others are fitted again, from there, within
    the evaluations ``left`` or :data:`SETTLING`, whichever is more (on EMPS the rung's fit crawls until its
    evaluation limit). The refit is kept if its cost is within :data:`ON_BOUND` of the fit's. At an interior
    optimum no unknown presses on a bound, or setting it on the bound costs far more, and the fit is as it was.
    The probe and the refit run on a copy of ``problem``: an evaluation on a bound can be stiff, and on the original
    it changed what the fit did next (on Bouc-Wen the hysteresis' refit then failed in TR-BDF2 and rung 1 took a
    cubic spring)."""
    lower, upper = bounds
    pressing_low, pressing_high = np.isfinite(lower) & (result.grad > 0), np.isfinite(upper) & (result.grad < 0)
    pressing = pressing_low | pressing_high
    if not pressing.any():
        return result
    on = np.where(pressing_low, lower, np.where(pressing_high, upper, result.x))
    trial = copy.deepcopy(problem)  # the fit's own solver, warm starts and counts stay as they are
    if 0.5 * float(np.sum(trial.residual(on) ** 2)) > (1.0 + ON_BOUND) * result.cost:
        return result
    width = HELD_WIDTH * np.maximum(1.0, np.abs(on))
    held = (np.where(pressing_low, on, np.where(pressing_high, on - width, lower)),
            np.where(pressing_low, on + width, np.where(pressing_high, on, upper)))
    settled = _trf(trial, np.clip(on, *held), held, max(left, SETTLING), ftol)
    return settled if settled.cost <= (1.0 + ON_BOUND) * result.cost else result


def _checked_unknowns(physics: AbstractPhysics, records: list[Record], initial_state: InitialState,
                      start_states: Sequence[torch.Tensor] | None) -> list[str]:
    """The learnable parameters' names, after checking that the records' channels are the physics', that the fit has
    unknowns, and that ``start_states`` fits."""
    initial_state.guesses(physics, records, start_states)  # refuses start_states that do not fit the policy
    for record in records:
        check_channels(physics, record)
    check_outputs_vary(records)
    names = physics.learnable_names()
    if not names and not initial_state.unknowns(physics, records):
        raise ConfigurationError(f"{physics.display_name} has no learnable parameter; call set_learnable(name) first")
    return names


class _StepCheck:
    """The solver the step check (:mod:`torchpaml._fit.resolution`) resolves at a point of ``problem``: the whole
    check at an optimum, only the step's stability at the start (a start's step error only delays the fit, whose
    optimum is checked). Where the solver cannot resolve it, the fit goes on with its
    :meth:`~torchpaml.Solver.fallback` (the default's TR-BDF2 for physics too stiff for RK4), if it has one."""

    def __init__(self, problem: TrustRegionProblem):
        self.problem = problem

    def solver(self, x: np.ndarray, optimum: bool) -> Solver:
        problem, current = self.problem, self.problem.solver
        residual = problem.evaluate(x)[0]  # also sets the model to x
        fallback = current.fallback()
        most_stable = MAX_SUBSTEPS if fallback is None else STIFF_SUBSTEPS  # beyond, the fallback goes on
        try:
            if not optimum:
                return stable_solver(problem.physics, current, problem.records, problem.starts(x), most_stable)
            return resolved_solver(problem.physics, current, problem.records, problem.starts(x),
                                   float(np.linalg.norm(residual)), most_stable, problem.outputs(residual))
        except ResolutionError:
            if fallback is None:
                raise
            return fallback


def _estimate(problem: TrustRegionProblem, x: np.ndarray) -> PhysicsEstimate:
    """The :class:`PhysicsEstimate` at the optimum ``x`` (the model set there), its uncertainty included."""
    physics, names, records = problem.physics, problem.names, problem.records
    residual, jacobian = problem.evaluate(x)
    values = physics.physical_parameters()
    residual, jacobian = torch.from_numpy(residual.copy()), torch.from_numpy(jacobian.copy())
    initial_states = [x0[0] if x0 is not None else physics.initial_state(1)[0] for x0 in problem.starts(x)]
    state_names = problem.initial_state.labels(physics, records)
    slopes = torch.cat([constraint_slopes(physics, names), torch.ones(len(state_names), dtype=torch.float64)])
    x0_values = x[len(names):].tolist()
    estimates = torch.tensor([values[n] for n in names] + x0_values, dtype=torch.float64)
    uncertainty = parameter_uncertainty(names + state_names, estimates, residual, jacobian / slopes,
                                        at_limit=_at_limit(physics, names, x, slopes))
    warn_if_unidentifiable(uncertainty, physics.display_name)
    return PhysicsEstimate({n: values[n] for n in names}, float(torch.linalg.vector_norm(residual)), residual,
                           jacobian, problem.simulations, uncertainty, initial_states,
                           _simulating(problem.solver, physics, records), physics)


def _at_limit(physics: AbstractPhysics, names: list[str], x: np.ndarray, slopes: torch.Tensor) -> list[str]:
    """The parameters at the limit of their constraint: its slope is 0, or the raw value is at its limit."""
    limits = raw_limits(physics, names)
    return [n for i, n in enumerate(names) if slopes[i] == 0 or abs(x[i]) >= limits[i]]


def _simulating(solver: Solver, physics: AbstractPhysics, records: list[Record]) -> Solver:
    """The solver that simulates the fitted model as the fit did (:meth:`~torchpaml.Solver.simulating`): ``Exact()``
    where every record takes the exact path, else the one the others take."""
    used = [solver.simulating(physics, r.elapsed) for r in records]
    return next((s for s in used if s != Exact()), used[0])


def estimate_initial_state(physics: AbstractPhysics, record: Record, samples: int | None = None,
                           solver: Solver | None = None) -> torch.Tensor:
    """The initial state (n_state,) that best explains the first ``samples`` of ``record`` (all if ``None``).

    The parameters stay as they are: a frozen copy of ``physics`` goes through :func:`fit_physics`
    with ``Estimate()``. Benchmarks that allow a few samples for initialisation (the
    Silverbox's first 50) score a model from this state.
    """
    frozen = copy.deepcopy(physics)
    frozen.set_learnable(*frozen.learnable_names(), learn=False)
    window = record if samples is None else record.window(0, samples)
    return fit_physics(frozen, window, initial_state=Estimate(), solver=solver).initial_states[0]
