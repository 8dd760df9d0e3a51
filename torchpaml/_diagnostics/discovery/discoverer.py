"""The discovery stage of a diagnosis: how a force outside the library is discovered, as one frozen value that holds
the search (:meth:`Discoverer.discover`)."""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch

from torchpaml._budget import REFIT_BUDGET, Budget
from torchpaml._data import Record
from torchpaml._data.simulation import simulate_record
from torchpaml._diagnostics.discovery.closed_form_search import ClosedFormSearch, Regressed
from torchpaml._diagnostics.discovery.result import Discovery, closed_form_samples, library_best
from torchpaml._diagnostics.discovery.regressors import columns
from torchpaml._diagnostics.results import Ranking
from torchpaml._diagnostics.ranking.scoring import as_records, scored_mismatch
from torchpaml._errors import ConfigurationError
from torchpaml._fit.neural_force import fit_neural_force
from torchpaml._fit.sparse_regression import SparseRegression
from torchpaml._physics.terms import TermLibrary, variables_of
from torchpaml._fit.one_thread import one_thread

__all__ = ["Discoverer", "discover_missing_force"]

log = logging.getLogger("torchpaml._diagnostics.discovery.result")


@dataclass(frozen=True)
class Discoverer:
    """The settings of :func:`~torchpaml.discover_missing_force` (its module docstring has the method).

    Attributes:
        library: the terms to regress on (:class:`~torchpaml.TermLibrary`; ``TermLibrary(terms=[...])`` adds the
            user's own, sympy strings over the physics' variables).
        regression: the sparse regression (:class:`~torchpaml.SparseRegression`).
        max_iter: L-BFGS iterations of the neural rate.
        max_nfev: iteration limit of the closed form's refit.
        seed: seed of the network's initial weights.
        always: search even where the ladder's last rung is complete (its residual is noise that the orthogonal
            residual cannot reduce); by default the discovery then says so and stops (``--discover_always``).
    """

    library: TermLibrary = field(default_factory=TermLibrary)
    regression: SparseRegression = field(default_factory=SparseRegression)
    max_iter: int = 60
    max_nfev: int = 40
    seed: int = 0
    always: bool = False

    def __post_init__(self):
        for name in ("max_iter", "max_nfev"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ConfigurationError(f"{name} must be a whole number, at least 1; got {value!r}")

    @one_thread()  # one arithmetic path (torchpaml._fit.one_thread)
    def discover(self, ranking: Ranking, train: Sequence[Record], validation: Sequence[Record],
                 deadline: float | None = None, complete: bool = False) -> Discovery:
        """Discover the force or rate missing from ``ranking``'s physics (:mod:`~torchpaml._diagnostics.discovery.result`)
        with these settings; where the rung is ``complete`` (``Adequacy.complete``) and not :attr:`always`, a
        discovery that says so, without a search (``Discovery.searched`` false).

        Args:
            ranking: a ranking (the ladder's last): its baseline is the fitted physics to extend, its best refitted
                physical entry the library's best effect; its ``rule`` judges the closed form, and its
                ``initial_state`` applies.
            train: the training records the ranking was made on.
            validation: the validation records the ranking was made on.
            deadline: a ``time.perf_counter()`` time by which the search ends (the diagnosis' ``budget``).
            complete: whether the ranking's rung is complete at the noise level (``Adequacy.complete``).
        """
        if complete and not self.always:
            reason = (f"{ranking.baseline.name} is complete at this noise level (its residual is noise that the "
                      "orthogonal residual cannot reduce): nothing to discover; to search anyway, "
                      "Discoverer(always=True) or --discover_always")
            log.info("discovery: %s", reason)
            return Discovery(ranking.baseline, library_best(ranking), None, None, None, None, False, reason, {},
                             searched=False)
        return self._search(ranking, train, validation, deadline)

    def _search(self, ranking: Ranking, train: Record | Sequence[Record], validation: Record | Sequence[Record],
                deadline: float | None) -> Discovery:
        """The search (:mod:`~torchpaml._diagnostics.discovery.result`): a neural rate, the terms' columns along its
        trajectories, the sparse regression, and the closed forms' refits, each within the ``deadline``. Each closed
        form's refit may take ten fits of ``max_nfev`` evaluations at its own cost (it is several fits: the form,
        its pruning, what remains), a screen its share of that (:mod:`torchpaml._budget`). A form stopped by either
        is named in ``Discovery.undecided``, and so is a neural rate that stopped (the search goes on from where it
        stood)."""
        train, validation = as_records(train), as_records(validation)
        library, regression, max_nfev = self.library, self.regression, self.max_nfev
        baseline = ranking.baseline
        physics = baseline.model
        variables, equations = variables_of(physics)
        terms = library.build(physics)
        # a closed form's refit is several fits (the form, its pruning, what remains), each up to max_nfev evaluations
        limits = Budget("", evaluations=REFIT_BUDGET * max_nfev, deadline=math.inf if deadline is None else deadline)
        budget = Budget(f"discovery: training a neural rate on {physics.display_name}", deadline=limits.deadline)
        log.info("discovery: training a neural rate on %s (at most %s)", physics.display_name, budget.describe())
        neural = fit_neural_force(physics, train, baseline.train_states, max_iter=self.max_iter, seed=self.seed,
                                  solver=baseline.solver, budget=budget)
        stopped = [] if neural.stopped is None else [f"the neural rate: over budget ({neural.stopped:.1f} s)"]
        with torch.no_grad():
            neural_validation = scored_mismatch(
                validation, [simulate_record(neural.model, r, x0, solver=neural.solver)[0]
                             for r, x0 in zip(validation, baseline.validation_states, strict=True)], ranking.initial_state)
        log.info("discovery: %d terms on %d equation(s) through the output", len(terms), len(equations))
        data = columns(neural, baseline, terms, equations, variables, train, ranking.initial_state)
        log.info("discovery: sparse regression on %d terms", len(terms) * len(equations))
        regressed = Regressed.of(data, [(e, t) for e in equations for t in terms], regression)
        best_effect = library_best(ranking)
        samples = {**data.samples, "closed_form": torch.zeros_like(data.samples["learned"])}
        found = functools.partial(Discovery, baseline, best_effect, neural.mismatch, neural_validation)
        if not regressed.proposed:
            return found(None, None, False, "the sparse regression kept no term: nothing is missing that the physics "
                         "cannot make", samples, stopped)
        search = ClosedFormSearch(ranking, best_effect, train, validation, data, regressed, max_nfev, limits)
        discovered, missing, reason = search.best(regression.max_terms)
        undecided = stopped + search.undecided
        if undecided:
            reason += f"; undecided: {'; '.join(undecided)}"
        if discovered is None:
            return found(None, None, False, reason, samples, undecided)
        effect = discovered.model.effects["discovered"]
        if missing is None:  # the closed form does not improve on the physics: nothing is missing
            return found(None, None, False, f"the best closed form, {effect.expression()}, does not improve on the "
                         f"physics: {reason}", samples, undecided)
        samples["closed_form"] = closed_form_samples(effect, data.samples, variables, next(iter(equations)))
        return found(effect, discovered, missing, reason, samples, undecided)


def discover_missing_force(ranking: Ranking, train: Record | Sequence[Record], validation: Record | Sequence[Record],
                           *, library: TermLibrary | None = None, regression: SparseRegression | None = None,
                           max_iter: int = 60, max_nfev: int = 40, seed: int = 0,
                           deadline: float | None = None) -> Discovery:
    """``Discoverer(library, regression, max_iter, max_nfev, seed, always=True).discover(ranking, train, validation,
    deadline)``: the search in one call, on the ranking's physics whatever its rung's adequacy (:meth:`Discoverer.discover`)."""
    return Discoverer(library or TermLibrary(), regression or SparseRegression(), max_iter, max_nfev, seed,
                      always=True).discover(ranking, train, validation, deadline)
