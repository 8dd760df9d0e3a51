r"""Discover what is missing outside the library: a neural rate in the ODE, then a closed form.

:func:`discover_missing_force` runs on a ranking's baseline (the ladder's last rung): any physics at
its fitted parameters $\hat\theta$, $\dot x = f_{\hat\theta}(t, x, u)$, $y = h(x, u)$.

1. **Neural rate** (a universal differential equation, :func:`~torchpaml._fit.fit_neural_force`):
   $\dot x = f_{\hat\theta} + E\,\mathrm{MLP}(x, u)$, the physics held, fitted by output error. $E$ picks
   the equations a term may enter (:func:`~torchpaml._physics.terms.variables_of`): the acceleration of
   second-order physics, every state's rate otherwise. Its trajectory gives the states that the
   records do not measure.
2. **Closed form.** Along that trajectory every term $\theta_i$ of the library
   (:class:`~torchpaml._physics.TermLibrary`) on every equation $e$ is passed through the physics'
   tangent-linear response $\mathcal L_e$ along its own trajectory
   (:func:`~torchpaml._simulate.response.forced_response`; exact for linear physics), so that terms
   are compared by what they do to the output, where the records can tell them apart. The learned
   rate, seen the same way, guides the search. What the physics' own parameters (and, when they are
   estimated, the initial states) can produce, the columns of its output Jacobian, is projected out
   (the first-order incompatibility of Kuang & Lin): the directions of the unit-scaled Jacobian that the
   records determine, singular value at least $1/$:data:`~torchpaml._fit.uncertainty.COLLINEARITY_LIMIT`
   (the identifiability check's limit; along a sloppier combination first order would move the
   parameters far beyond where it holds). Then the sparse regression
   (:class:`~torchpaml._fit.sparse_regression.SparseRegression`: STLSQ and a forward path, scored by
   the extended BIC, which pays for the size of the search) picks the few terms that explain the
   measured residual $y - \hat y_{\text{physics}}$.
3. **Refit, with honest numbers** (:func:`~torchpaml._diagnostics.closed_form.refit_closed_form`). The
   closed form becomes a :class:`~torchpaml._physics.DiscoveredForce` refitted with the physics by
   output error. A smoothed sign's width is bounded to what the record resolves (:func:`width_range`:
   from the typical change of $s$ over one sample to its RMS), and replaced by its limit at an edge
   (a sign, or a linear term); terms whose standard error exceeds their coefficient, and terms too
   small to matter, are dropped, and the rest refitted. Where that support does not hold (no term is
   determined, or it does not beat the physics), or where the records do not determine a combination of
   the physics' parameters (a direction left in the projection, along which first order is unreliable:
   linear tanks whose fit sits at a double pole), first order may be misled, and the search goes by refits:
   every single term is also fitted with the physics by a few output-error iterations (:data:`SCREEN_NFEV`),
   the :data:`SCREEN` that fit best are refitted in full, and the best of all by the criterion is kept. From
   there it goes forward: the kept support plus each other term is screened the same way, and the best
   extension is kept while it lowers the criterion by more than the rule's threshold (the pruning's margin,
   the other way), up to the regression's ``max_terms``.
4. **Judge.** The closed form is scored on the validation records like every rung and
   **recommended** when it beats the physics by the ranking's rules and the best library effect's
   criterion by more than the threshold; otherwise the library effect, which has a name, is
   preferred. A closed form that does not beat the physics means that nothing is missing: the
   expression is ``"0"``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch

from torchpaml._errors import ConfigurationError
from torchpaml._data import Experiment
from torchpaml._diagnostics.closed_form import fit_closed_form, refit_closed_form
from torchpaml._diagnostics.ranking import EffectEvidence, ModelScore, Ranking, as_records
from torchpaml._diagnostics.selection import SelectionRule
from torchpaml._budget import REFIT_BUDGET, Budget, OverBudget
from torchpaml._fit.neural_force import NeuralForceFit, fit_neural_force
from torchpaml._fit.sparse_regression import SparseRegression
from torchpaml._fit.uncertainty import COLLINEARITY_LIMIT
from torchpaml._metrics import mismatch
from torchpaml._physics.discovered import DiscoveredForce
from torchpaml._physics.terms import TermLibrary, compile_term, state_columns, variables_of, width_symbol
from torchpaml._diagnostics.probes import assigned
from torchpaml._data.simulation import record_jacobian, record_response, record_states, simulate_record

__all__ = ["Discovery", "discover_missing_force", "width_range"]

log = logging.getLogger(__name__)

#: Two term columns whose |cosine| is above 1 - DUPLICATE are one term on this record.
DUPLICATE = 1e-9
#: Relative central-difference step of the physics' own sensitivities.
STEP = 1e-6
#: Where the sparse regression's support may be misled (module docstring, step 3), every single term (then every
#: one-term extension of the kept support) is fitted with the physics for at most SCREEN_NFEV evaluations, and the
#: SCREEN that fit the training records best are refitted in full.
SCREEN, SCREEN_NFEV = 4, 10
#: Significant digits to which the search compares mismatches and criteria (:func:`_settled`).
SETTLED_DIGITS = 5


@dataclass
class Discovery:
    """What :func:`discover_missing_force` found (module docstring); :func:`~torchpaml.discovery_to_dict` makes ``discovery.json``.

    ``effect`` is the refitted closed form (``None`` when nothing was kept); ``samples`` holds, along the
    first training record's neural trajectory, each variable, and the learned rate and the closed form's
    rate on the first equation, for :func:`~torchpaml.discovery_figure`. ``undecided`` names the forms whose fit
    stopped over its budget (:mod:`torchpaml._budget`), and a search that the diagnosis' budget ended.
    """

    physics: ModelScore
    library_best: EffectEvidence | None
    neural_train: float
    neural_validation: float
    effect: DiscoveredForce | None
    discovered: ModelScore | None
    recommended: bool
    reason: str
    samples: dict[str, torch.Tensor] = field(repr=False)
    undecided: list[str] = field(default_factory=list)

    @property
    def expression(self) -> str | dict[str, str]:
        return "0" if self.effect is None else self.effect.expression()

    @property
    def text(self) -> str:
        """The expression on one line: ``"equation: expression; ..."`` for several equations."""
        found = self.expression
        return found if isinstance(found, str) else "; ".join(f"{k}: {v}" for k, v in found.items())


def width_range(values: torch.Tensor) -> tuple[float, float]:
    r"""The smoothed sign's widths that a record of ``values`` (samples,) resolves: from the median change over
    one sample (a narrower sign is a sign at this sampling) to the RMS (a wider one is linear where the
    values lie)."""
    low = float(values.diff().abs().median())
    high = float(values.square().mean().sqrt())
    return max(low, 1e-9 * high, 1e-300), max(high, 2 * low, 1e-300)


@dataclass
class _Columns:
    """The regression's data, records concatenated: the terms' responses (samples, columns), the learned rate's
    (samples,), the measured residual (samples,), the physics' Jacobian (samples, p), the raw term values on the
    first record's trajectory, and each sign variable's width range."""

    responses: torch.Tensor
    learned: torch.Tensor
    measured: torch.Tensor
    jacobian: torch.Tensor
    samples: dict[str, torch.Tensor]
    widths: dict[str, tuple[float, float]]


def _columns(neural: NeuralForceFit, baseline: ModelScore, terms: list[str], equations: dict[str, int],
             variables: tuple[str, ...], train: Sequence[Experiment], estimate: bool) -> _Columns:
    """:class:`_Columns` along the neural model's trajectories (module docstring, step 2), around the fitted physics
    of ``baseline`` from its training records' initial states."""
    physics, solver, starts = baseline.model, baseline.solver, baseline.train_states
    compiled = [compile_term(t, variables) for t in terms]
    trajectories = [record_states(neural.model, record, x0, neural.solver)
                    for record, x0 in zip(train, starts, strict=True)]
    index = state_columns(physics)
    signs = sorted({w for c in compiled for w in c.widths})
    by_width = {width_symbol(s): s for s in index}
    widths = {w: width_range(torch.cat([x[:, index[by_width[w]]] for x in trajectories])) for w in signs}
    names = physics.learnable_names()
    parts: dict[str, list[torch.Tensor]] = {"responses": [], "learned": [], "measured": [], "jacobian": []}
    samples: dict[str, torch.Tensor] = {}
    n = physics.state_dim
    for record, x0, states in zip(train, starts, trajectories, strict=True):
        values = {name: states[:, i] for name, i in index.items()}
        values["u"] = record.u[:, 0]
        values.update({w: torch.tensor(2 * low, dtype=states.dtype) for w, (low, _) in widths.items()})
        rates = []
        for equation, state in equations.items():
            for term in compiled:
                rate = torch.zeros(len(record.t), n, dtype=states.dtype)
                rate[:, state] = term.evaluate(values)
                rates.append(rate)
        with torch.no_grad():
            learned = neural.model.learned(states, record.u)
        responses = record_response(physics, record, x0, torch.stack([*rates, learned]), solver)
        parts["responses"].append(responses[:-1, :, 0].T)
        parts["learned"].append(responses[-1, :, 0])
        y, J = record_jacobian(physics, names[:1], record, x0, initial_state=estimate, solver=solver) if estimate \
            else (simulate_record(physics, record, x0, solver=solver), None)
        own = _own_sensitivities(physics, names, states, record.u)  # (N, n + n_output, p)
        own_responses = record_response(physics, record, x0, own[:, :n].movedim(-1, 0), solver)
        columns = own_responses[:, :, 0].T + own[:, n, :]
        if estimate:
            columns = torch.cat([columns, J[0, :, 0, len(names[:1]):]], dim=1)  # the initial states' free responses
        parts["measured"].append((record.y - y[0])[:, 0])
        parts["jacobian"].append(columns)
        if not samples:
            first = next(iter(equations.values()))
            samples = {**{v: values[v] for v in variables}, "learned": learned[:, first]}
    return _Columns(*(torch.cat(parts[k]) for k in ("responses", "learned", "measured", "jacobian")), samples, widths)


def _own_sensitivities(physics, names: list[str], states: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    r"""$\partial f/\partial\theta_j$ and $\partial h/\partial\theta_j$ at the given states, (N, n_state + n_output, p),
    by central differences in each physical parameter $\theta_j$: what the physics' own parameters can change,
    evaluated on the same trajectory as the terms."""
    t = torch.zeros(len(states), dtype=states.dtype)
    values = physics.physical_parameters()
    columns = []
    with torch.no_grad():
        for name in names:
            step = STEP * max(1.0, abs(values[name]))
            ends = []
            value = values[name]
            points = next(p for p in ((value + step, value - step), (value + step, value), (value + 2 * step, value + step))
                          if assigned(physics, name, p[1]))  # one-sided at a constraint's edge
            for point in points:
                physics.assign(**{name: point})
                ends.append(torch.cat([physics.derivative(t, states, u), physics.output(states, u)], dim=-1))
            assigned(physics, name, value)
            columns.append((ends[0] - ends[1]) / (points[0] - points[1]))
    width = physics.state_dim + physics.output_dim
    return torch.stack(columns, dim=-1) if columns else torch.zeros(len(states), width, 0, dtype=states.dtype)


def discover_missing_force(
    ranking: Ranking,
    train: Experiment | Sequence[Experiment],
    validation: Experiment | Sequence[Experiment],
    *,
    library: TermLibrary | None = None,
    regression: SparseRegression | None = None,
    max_iter: int = 60,
    max_nfev: int = 40,
    seed: int = 0,
    deadline: float | None = None,
) -> Discovery:
    """Discover the force or rate missing from the ranking's physics (module docstring).

    Args:
        ranking: a ranking (:func:`~torchpaml._diagnostics.rank_missing_effects`; the ladder's last): its
            baseline is the fitted physics to extend, its best refitted physical entry the library's best effect;
            its ``rule`` judges the closed form, and its ``initial_state`` option applies.
        train: the training record(s) the ranking was made on.
        validation: the validation record(s) the ranking was made on.
        library: the terms to regress on (default :class:`~torchpaml._physics.TermLibrary`: products of degree
            up to 3, sign-like products, square roots).
        regression: the sparse regression (default :class:`~torchpaml._fit.sparse_regression.SparseRegression`:
            at most 4 terms).
        max_iter: L-BFGS iterations of the neural rate.
        max_nfev: iteration limit of the closed form's refit.
        seed: seed of the network's initial weights.
        deadline: a ``time.perf_counter()`` time by which the search by refits ends (the diagnosis' ``budget``).
            Each fit has its own budget too: :data:`~torchpaml._budget.REFIT_BUDGET` times its evaluation limit at
            the cost of its first evaluations. A form stopped by either is named in ``Discovery.undecided``.
    """
    train, validation = as_records(train), as_records(validation)
    library, regression = library or TermLibrary(), regression or SparseRegression()
    baseline, rule, initial_state = ranking.baseline, ranking.rule, ranking.initial_state
    physics = baseline.model
    if physics.output_dim != 1 or physics.input_dim != 1:
        raise ConfigurationError(f"discovery handles one input and one output; {physics.display_name} has "
                         f"{physics.input_dim} and {physics.output_dim}")
    variables, equations = variables_of(physics)
    terms = library.build(physics)
    log.info("discovery: training a neural rate on %s", physics.display_name)
    neural = fit_neural_force(physics, train, baseline.train_states, max_iter=max_iter, seed=seed,
                              solver=baseline.solver)
    with torch.no_grad():
        neural_validation = mismatch(torch.cat([r.y for r in validation]),
                                     torch.cat([simulate_record(neural.model, r, x0, solver=neural.solver)[0]
                                                for r, x0 in zip(validation, baseline.validation_states, strict=True)]))
    log.info("discovery: %d terms on %d equation(s) through the output", len(terms), len(equations))
    data = _columns(neural, baseline, terms, equations, variables, train, initial_state == "estimate")
    J = data.jacobian
    U, S, _ = torch.linalg.svd(J / J.norm(dim=0).clamp_min(1e-300), full_matrices=False)
    Q = U[:, S * COLLINEARITY_LIMIT >= 1]  # what the physics makes by moves the records determine
    log.debug("discovery: the physics' unit-scaled Jacobian has singular values %s; %d of them at least 1/%g",
              [f"{v:.4g}" for v in S.tolist()], Q.shape[1], COLLINEARITY_LIMIT)

    def projected(M: torch.Tensor) -> torch.Tensor:
        return M - Q @ (Q.T @ M)

    columns = projected(data.responses)
    norms = columns.norm(dim=0)
    pairs = [(e, t) for e in equations for t in terms]
    usable = _distinct([i for i in range(len(pairs)) if norms[i] > 1e-3 * data.responses[:, i].norm()],
                       columns / norms.clamp_min(1e-300))  # the rest the physics makes, or an earlier term does
    support = regression.select(columns[:, usable] / norms[usable], projected(data.measured[:, None])[:, 0],
                                [projected(data.learned[:, None])[:, 0]])
    chosen = [usable[i] for i in support]
    library_best = next((e for e in ranking.entries if e.refit is not None and not e.unphysical), None)
    samples = {**data.samples, "closed_form": torch.zeros_like(data.samples["learned"])}
    if not chosen:
        return Discovery(baseline, library_best, neural.mismatch, neural_validation, None, None, False,
                         "the sparse regression kept no term: nothing is missing that the physics cannot make", samples)

    def first_order(kept: list[tuple[str, str]]) -> list[float] | None:
        """The coefficients of ``kept`` by least squares on the responses (with the physics' Jacobian), or ``None``
        where a term is not among the regressed ones (a limit replaced it)."""
        if any(p not in pairs for p in kept):
            return None
        columns = torch.cat([J, data.responses[:, [pairs.index(p) for p in kept]]], dim=1)
        return torch.linalg.lstsq(columns, data.measured[:, None]).solution[J.shape[1]:, 0].tolist()

    undecided: list[str] = []
    end = math.inf if deadline is None else deadline

    def refitted(kept: list[tuple[str, str]]) -> tuple[ModelScore | None, bool | None, str]:
        """The closed form of ``kept`` refitted, whether it is missing (:func:`_judge`) and why."""
        form = ", ".join(f"{t} ({e})" for e, t in kept)
        log.info("discovery: refitting %s", form)
        budget = Budget(f"discovery: refitting {form}", evaluations=REFIT_BUDGET * max_nfev, deadline=end)
        try:
            score = refit_closed_form(physics, kept, first_order(kept), data.widths, train, validation, rule,
                                      max_nfev, initial_state, first_order, budget, baseline.solver)
        except OverBudget as over:
            undecided.append(f"{form}: over budget ({over.seconds:.1f} s)")
            return None, None, f"its refit stopped over budget ({over.seconds:.1f} s)"
        if score is None:
            return None, None, "no term of the closed form is determined by the records"
        return score, *_judge(baseline, library_best, score, rule)

    proposed = [pairs[i] for i in chosen]  # the regression's support

    def screened(base: list[tuple[str, str]], starts: list[float]) -> list[tuple[ModelScore | None, bool | None, str]]:
        """``base`` (fitted coefficients ``starts``) plus each usable term not in it, fitted with the physics for
        :data:`SCREEN_NFEV` evaluations; the :data:`SCREEN` that fit the training records best, refitted in full."""
        short = {}
        extras = [pairs[i] for i in usable if pairs[i] not in base and base + [pairs[i]] != proposed]  # refitted already
        for i, extra in enumerate(extras, 1):
            budget = Budget(f"discovery: screening {extra[1]}", evaluations=REFIT_BUDGET * SCREEN_NFEV, deadline=end)
            if budget.expired:
                undecided.append(f"the screen beside [{', '.join(t for _, t in base)}]: the diagnosis' budget was "
                                 f"spent after {i - 1} of {len(extras)} terms")
                break
            kept = base + [extra]
            log.info("discovery: screening %d of %d: %s (%s)", i, len(extras), extra[1], extra[0])
            try:
                fitted = fit_closed_form(physics, kept, first_order(kept) or [*starts, 0.0], data.widths, train,
                                         SCREEN_NFEV, initial_state, budget, baseline.solver)
            except OverBudget as over:
                undecided.append(f"{', '.join(t for _, t in kept)}: screen over budget ({over.seconds:.1f} s)")
                continue
            if fitted is not None:
                short[extra] = fitted[1].mismatch
        ordered = sorted(short, key=lambda extra: _settled(short[extra]))  # ties: the library's order
        log.debug("discovery: screened mismatches %s", [(f"{short[e]:.6g}", e[1], e[0]) for e in ordered[:2 * SCREEN]])
        return [refitted(base + [extra]) for extra in ordered[:SCREEN]]

    candidates = [refitted(proposed)]
    sloppy = Q.shape[1] < J.shape[1]  # a combination of the physics' parameters that the records do not determine
    search = candidates[0][1] is None or sloppy  # first order may be misled: a search by refits
    if search:
        log.info("discovery: the first-order closed form %s; screening %d single terms",
                 "rests on a physics the records do not determine" if sloppy else "does not hold", len(usable))
        candidates += screened([], [])
    held = [c for c in candidates if c[1] is not None]
    best = min(held, key=lambda c: _settled(c[0].criterion)) if held else candidates[0]
    while search and best[1] is not None and len(support := _support(best[0])) < regression.max_terms:
        log.info("discovery: screening one more term beside %s", ", ".join(t for _, t in support[0]))
        extended = [c for c in screened(*support) if c[1] is not None]  # forward, one term at a time
        top = min(extended, key=lambda c: _settled(c[0].criterion), default=None)
        if top is None or top[0].criterion >= best[0].criterion - rule.threshold:
            break
        best = top
    discovered, missing, reason = best
    if undecided:
        reason += f"; undecided: {'; '.join(undecided)}"
    if discovered is None:
        return Discovery(baseline, library_best, neural.mismatch, neural_validation, None, None, False, reason, samples,
                         undecided)
    effect = discovered.model.effects["discovered"]
    samples["closed_form"] = _closed_form_samples(effect, data.samples, variables, next(iter(equations)))
    if missing is None:  # the closed form does not improve on the physics: nothing is missing
        samples["closed_form"] = torch.zeros_like(samples["learned"])
        return Discovery(baseline, library_best, neural.mismatch, neural_validation, None, None, False,
                         f"the best closed form, {effect.expression()}, does not improve on the physics: {reason}", samples,
                         undecided)
    return Discovery(baseline, library_best, neural.mismatch, neural_validation, effect, discovered, missing, reason,
                     samples, undecided)


def _settled(value: float) -> float:
    """``value`` to :data:`SETTLED_DIGITS` significant digits: the search's choices (which screened terms to refit,
    which refit to keep) compare these, so that forms whose figures differ only by rounding (a constant on either
    tank of the linear tanks screens to the same mismatch to 6 digits) tie and keep the library's order, rather than
    letting the machine's rounding choose between them."""
    return float(f"{value:.{SETTLED_DIGITS}g}")


def _support(score: ModelScore) -> tuple[list[tuple[str, str]], list[float]]:
    """The refitted closed form's ``(equation, term)`` pairs and their coefficients, the gain folded in."""
    effect = score.model.effects["discovered"]
    values, gain = effect.values(), float(effect.gain.detach())
    return (list(zip(effect.equations, effect.terms, strict=True)),
            [gain * values[name] for name in effect.parameter_names])


def _distinct(indices: list[int], unit: torch.Tensor) -> list[int]:
    """``indices`` without the columns of ``unit`` (unit norm) that repeat an earlier one (|cosine| > 1 - 1e-9):
    ``Abs(level)`` and ``level*tanh(level/eps)`` are ``level`` on a record where the level stays positive, and
    the library's order puts the plainer spelling first."""
    kept: list[int] = []
    for i in indices:
        if not kept or float((unit[:, kept].T @ unit[:, i]).abs().max()) < 1 - DUPLICATE:
            kept.append(i)
    return kept


def _closed_form_samples(effect: DiscoveredForce, samples: dict[str, torch.Tensor], variables: tuple[str, ...],
                         equation: str) -> torch.Tensor:
    """The closed form's rate on ``equation`` at the figure's samples."""
    values = {**{v: samples[v] for v in variables}, **{w: getattr(effect, w).detach() for w in effect.width_names}}
    total = torch.zeros_like(samples["learned"])
    for name, term, eq in zip(effect.parameter_names, effect.terms, effect.equations, strict=True):
        if eq == equation:
            total = total + float(getattr(effect, name).detach()) * compile_term(term, None).evaluate(values)
    return total * float(effect.gain.detach())


def _judge(physics: ModelScore, library: EffectEvidence | None, discovered: ModelScore, rule: SelectionRule
           ) -> tuple[bool | None, str]:
    """``(None, why)`` when ``rule`` does not accept the closed form over the physics; else whether it is
    recommended over the best library effect (criterion lower by more than the threshold), and why."""
    why = rule.why_not(physics, discovered)
    if why is not None:
        return None, why
    gain = physics.criterion - discovered.criterion
    if library is not None:
        margin = library.refit.criterion - discovered.criterion
        if margin <= rule.threshold:
            return False, (f"the library effect {library.effect} explains the records as well (criterion "
                           f"{margin:+.1f} against it, needed more than {rule.threshold:g}): the named effect is "
                           "preferred")
        return True, f"it beats the physics by {gain:.1f} and the best library effect ({library.effect}) by {margin:.1f}"
    return True, f"it beats the physics by {gain:.1f}; no library effect was refitted"
