r"""The one physics fit: output error by a trust-region method, with forward-mode Jacobians.

$$ \hat\rho = \arg\min_\rho \tfrac12 \|r(\rho)\|^2, \qquad r = \frac{y - \mathcal H^{\theta(\rho)}[u]}{\|y\|} $$

over the raw (unconstrained) values $\rho$ of the learnable physical parameters $\theta$, all records
stacked. ``scipy.optimize.least_squares`` (``method="trf"``) solves it; its Jacobian
$\partial r/\partial\rho$ comes from :func:`~torchpaml._simulate.output_jacobian` (exact path for linear
physics, the parallel RK4 engine otherwise: one Newton solve and one sweep per parameter).

**Bounds** are the one bound mechanism: ``bounds={name: (lower, upper)}`` in physical units become
closed bounds on $\rho$ through the parameter's own constraint map (monotone, so the interval maps to
an interval), and the trust region keeps every iterate strictly inside. An optimum beyond a bound
ends within about 1e-9 of it (the paper's $\zeta$ capped at 5 for $\alpha = 10$).

The estimate carries its :class:`~torchpaml._fit.uncertainty.Uncertainty` (standard errors, 95 %
intervals, identifiability; ``physics.describe(estimate.uncertainty)`` prints them); an
:class:`~torchpaml._fit.uncertainty.IdentifiabilityWarning` names a combination the records do not determine.

Trial steps whose simulation blows up are rejected by the trust region (their residual is inf);
a start that blows up raises :class:`~torchpaml._errors.SimulationError`.

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
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
from scipy.optimize import least_squares

from torchpaml._data import Experiment
from torchpaml._errors import ConfigurationError, ResolutionError, SimulationError
from torchpaml._budget import Budget
from torchpaml._fit.resolution import MAX_SUBSTEPS, resolved_solver, stable_solver
from torchpaml._fit.uncertainty import Uncertainty, constraint_slopes, parameter_uncertainty, warn_if_unidentifiable
from torchpaml._physics.base import complete_state
from torchpaml._data.simulation import record_jacobian
from torchpaml._simulate.lti import exact_step
from torchpaml._simulate.sensitivity import raw_parameters
from torchpaml._simulate.stiffness import STIFF_SUBSTEPS
from torchpaml._simulate.solvers import TRBDF2, Auto, Exact, FixedStep, Solver, engine_solver
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
        solver: the solver the fit ended with (the step check): RK4 or TRBDF2 at whole substeps, or ``Exact()``
            where every record takes the exact path. Simulate the fitted model with it to simulate it as the fit
            did; fit a model built on this one with ``Auto(start=solver)``
            (:func:`~torchpaml._simulate.solvers.continued`) to start its step check here.
    """

    parameters: dict[str, float]
    mismatch: float
    residual: torch.Tensor
    jacobian: torch.Tensor
    evaluations: int
    uncertainty: Uncertainty
    initial_states: list[torch.Tensor]
    solver: Solver


def _raw_bounds(physics, names: list[str], bounds: dict[str, tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
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


def fit_physics(
    physics,
    records: Experiment | Sequence[Experiment],
    *,
    bounds: dict[str, tuple[float, float]] | None = None,
    initial_state: Literal["rest", "estimate"] = "rest",
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
            ``initial_state="estimate"`` it may have none (then only the initial states are fitted).
        records: one or more :class:`~torchpaml._data.Experiment`.
        bounds: ``{name: (lower, upper)}`` in physical units.
        initial_state: ``"rest"`` (each record starts at rest) or ``"estimate"`` (each record's initial
            state is fitted too, an unbounded unknown per state; see ``PhysicsEstimate.initial_states``).
        start_states: with ``initial_state="estimate"``, each record's starting guess (n_state,), or of
            the base's states of ``physics + effect`` (:func:`~torchpaml._physics.complete_state`) (default: rest).
        warm: one :class:`~torchpaml.WarmStart` per record that carries the RK4 engine's last solution into the
            fit's first Newton solve (``simulate(..., warm=)``, e.g. of a simulation at the start); default fresh ones.
        max_nfev: iteration limit of the trust region.
        ftol: the trust region stops when a step lowers the cost $\tfrac12\|r\|^2$ by less than this share of it
            (scipy's ``ftol``); the default fits to the last digits, a ranking's refits stop earlier.
        solver: ``RK4(...)`` or ``TRBDF2(...)``: the method and the substeps to start from (``"auto"``: one), or
            ``Auto()``/``None`` (the default): RK4 at one substep (or ``Auto``'s ``start``, a previous fit's
            solver), and TR-BDF2 where RK4 cannot resolve the optimum. The step check raises the substeps where
            the fitted output depends on the step (:mod:`torchpaml._fit.resolution`).
        budget: a :class:`~torchpaml._budget.Budget`: progress lines while the fit runs, and
            :class:`~torchpaml._budget.OverBudget` raised past its limit (default: neither).
    """
    if initial_state not in ("rest", "estimate"):
        raise ConfigurationError(f"initial_state must be 'rest' or 'estimate', got {initial_state!r}")
    estimate_x0 = initial_state == "estimate"
    switch = solver is None or isinstance(solver, Auto)  # may go on with the implicit method
    solver = _starting_solver(solver)
    records = [records] if isinstance(records, Experiment) else list(records)
    if start_states is not None and (not estimate_x0 or len(start_states) != len(records)):
        raise ConfigurationError(f"start_states needs initial_state='estimate' and one state per record ({len(records)}), got "
                         f"{len(start_states)} with initial_state={initial_state!r}")
    names = physics.learnable_names()
    if not names and not estimate_x0:
        raise ConfigurationError(f"{physics.display_name} has no learnable parameter; call set_learnable(name) first")
    p, n_state = len(names), physics.state_dim
    lower, upper = _raw_bounds(physics, names, bounds or {})
    if estimate_x0:
        lower = np.concatenate([lower, np.full(n_state * len(records), -np.inf)])
        upper = np.concatenate([upper, np.full(n_state * len(records), np.inf)])
    raw = list(raw_parameters(physics, names).values())
    targets = [r.y[None] for r in records]
    scale = float(torch.sqrt(sum(torch.sum(y**2) for y in targets)))
    count = {"simulations": 0, "cost": math.inf}  # the lowest cost so far
    memo: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
    warm = [WarmStart() for _ in records] if warm is None else list(warm)  # each record's last solution starts the next solve

    def starts(x: np.ndarray) -> list[torch.Tensor | None]:
        if not estimate_x0:
            return [None] * len(records)
        return [torch.from_numpy(x[p + i * n_state: p + (i + 1) * n_state].copy())[None] for i in range(len(records))]

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual (samples,) and Jacobian (samples, unknowns) at ``x``, once per point."""
        key = x.tobytes()
        if key not in memo:
            count["simulations"] += 1
            began = time.perf_counter()
            try:
                with budget.active() if budget is not None else contextlib.nullcontext():
                    value = computed(x)
                memo.clear()
                memo[key] = value
                count["cost"] = min(count["cost"], 0.5 * float(np.sum(memo[key][0] ** 2)))
            finally:  # a blow-up's time counts too
                if budget is not None:
                    budget.check(count["cost"], time.perf_counter() - began)
        return memo[key]

    def computed(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual and Jacobian at ``x``, computed."""
        with torch.no_grad():
            for tensor, value in zip(raw, x, strict=False):
                tensor.copy_(torch.tensor(value, dtype=torch.float64))
        parts = [record_jacobian(physics, names, r, x0, warm=w, initial_state=estimate_x0, solver=solver)
                 for r, w, x0 in zip(records, warm, starts(x), strict=True)]
        residual = torch.cat([(y - y_hat).flatten() for y, (y_hat, _) in zip(targets, parts, strict=True)]) / scale
        columns = []
        for i, (_, J) in enumerate(parts):  # each record's x0 columns go to its own block
            J = J.reshape(-1, J.shape[-1])
            block = torch.zeros(len(J), len(x) - p, dtype=torch.float64)
            if estimate_x0:
                block[:, i * n_state:(i + 1) * n_state] = J[:, p:]
            columns.append(torch.cat([J[:, :p], block], dim=1))
        jacobian = -torch.cat(columns) / scale
        return residual.numpy(), jacobian.numpy()

    def fun(x: np.ndarray) -> np.ndarray:
        try:
            return evaluate(x)[0]
        except SimulationError:
            return np.full(sum(y.numel() for y in targets), np.inf)

    guesses = [None] * len(records) if start_states is None else start_states
    guesses = [complete_state(physics, None if x is None else x.detach().reshape(1, -1), 1)[0].numpy()
               for x in guesses] if estimate_x0 else []
    start = np.clip(np.concatenate([torch.stack([v.detach() for v in raw]).numpy() if raw else np.zeros(0), *guesses]),
                    lower, upper)
    evaluate(start)  # raises SimulationError, naming the blow-up, at a bad start

    def solve(x: np.ndarray):
        return least_squares(fun, x, jac=lambda x: evaluate(x)[1], bounds=(lower, upper), method="trf",
                             x_scale="jac", max_nfev=max_nfev, ftol=ftol, xtol=1e-10, gtol=1e-10)

    most_stable = STIFF_SUBSTEPS if switch else MAX_SUBSTEPS  # beyond, the default solver goes on with TR-BDF2

    def outputs(residual: np.ndarray) -> list[torch.Tensor]:
        """Each record's output (time, n_output) from the residual $r = (y - \\hat y)/\\|y\\|$."""
        parts = (torch.from_numpy(residual) * scale).split([y.numel() for y in targets])
        return [y[0] - part.reshape(y.shape[1:]) for y, part in zip(targets, parts, strict=True)]

    def resolution(x: np.ndarray, optimum: bool) -> FixedStep:
        """The step check's solver at ``x`` (the model set to ``x`` first): the whole check at an optimum, only the
        step's stability at the start (a start's step error only delays the fit, whose optimum is checked)."""
        residual = evaluate(x)[0]
        try:
            if not optimum:
                return stable_solver(physics, solver, records, starts(x), most_stable)
            return resolved_solver(physics, solver, records, starts(x), float(np.linalg.norm(residual)), most_stable,
                                   outputs(residual))
        except ResolutionError:
            if not switch or isinstance(solver, TRBDF2):
                raise
            return TRBDF2(substeps=1, segment=solver.segment)  # stiff (or unresolved) for RK4: the implicit method

    x, result = start, None
    while (resolved := resolution(x, result is not None)) != solver or result is None:  # at the start, then each optimum
        if resolved != solver:
            solver = resolved
            memo.clear()
        result = solve(x)
        x = result.x
    linear = all(exact_step(physics, r.t) is not None for r in records)
    residual, jacobian = evaluate(result.x)
    values = physics.physical_parameters()
    residual, jacobian = torch.from_numpy(residual.copy()), torch.from_numpy(jacobian.copy())
    initial_states = [x0[0] if x0 is not None else physics.initial_state(1)[0] for x0 in starts(result.x)]
    state_names = [f"x0[{r.name}].{s}" for r in records for s in physics.state_names] if estimate_x0 else []
    slopes = torch.cat([constraint_slopes(physics, names), torch.ones(len(state_names), dtype=torch.float64)])
    x0_values = torch.cat(initial_states).tolist() if estimate_x0 else []
    estimates = torch.tensor([values[n] for n in names] + x0_values, dtype=torch.float64)
    uncertainty = parameter_uncertainty(names + state_names, estimates, residual, jacobian / slopes,
                                        at_limit=[n for n, slope in zip(names, slopes, strict=False) if slope == 0])
    warn_if_unidentifiable(uncertainty, physics.display_name)
    return PhysicsEstimate({n: values[n] for n in names}, float(torch.linalg.vector_norm(residual)), residual,
                           jacobian, count["simulations"], uncertainty, initial_states, Exact() if linear else solver)


def _starting_solver(solver: Solver | None) -> FixedStep:
    """The fixed-step solver a fit starts from (``fit_physics``'s ``solver``)."""
    if solver is None or isinstance(solver, Auto):
        return engine_solver(solver)
    if not isinstance(solver, FixedStep):
        raise ConfigurationError(f"fit_physics integrates with RK4(...) or TRBDF2(...) (or the default), got {solver!r}; "
                         "linear physics on a uniform grid takes the exact path by itself")
    return solver.at(1) if solver.substeps == "auto" else solver


def estimate_initial_state(physics, record: Experiment, samples: int | None = None,
                           solver: Solver | None = None) -> torch.Tensor:
    """The initial state (n_state,) that best explains the first ``samples`` of ``record`` (all if ``None``).

    The parameters stay as they are: a frozen copy of ``physics`` goes through :func:`fit_physics`
    with ``initial_state="estimate"``. Benchmarks that allow a few samples for initialisation (the
    Silverbox's first 50) score a model from this state.
    """
    frozen = copy.deepcopy(physics)
    frozen.set_learnable(*frozen.learnable_names(), learn=False)
    window = record if samples is None else record.window(0, samples)
    return fit_physics(frozen, window, initial_state="estimate", solver=solver).initial_states[0]
