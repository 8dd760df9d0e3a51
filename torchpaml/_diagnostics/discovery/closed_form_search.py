r"""The discovery's closed form (:mod:`~torchpaml._diagnostics.discovery.result`, steps 3 and 4): the sparse regression's
support (:class:`Regressed`), refitted with honest numbers, and, where first order may be misled, a search by refits
(:class:`ClosedFormSearch`)."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from torchpaml._budget import Budget, OverBudget
from torchpaml._data import Record
from torchpaml._diagnostics.discovery.closed_form import fit_closed_form, refit_closed_form
from torchpaml._diagnostics.discovery.regressors import Columns
from torchpaml._diagnostics.results import EffectEvidence, ModelScore, Ranking
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._fit.sparse_regression import SparseRegression
from torchpaml._fit.uncertainty import COLLINEARITY_LIMIT

__all__ = ["ClosedFormSearch", "Regressed", "SCREEN", "SCREEN_NFEV", "SETTLED_DIGITS"]

log = logging.getLogger(__name__)

#: A pair ``(equation, term)``: a library term on one state equation.
Pair = tuple[str, str]
#: A refitted closed form, whether it is missing (:func:`_judge`: ``None`` where the rule does not accept it), and why.
Judged = tuple[ModelScore | None, bool | None, str]

#: Two term columns whose |cosine| is above 1 - DUPLICATE are one term on this record.
DUPLICATE = 1e-9


#: Where the sparse regression's support may be misled (module docstring, step 3), every single term (then every
#: one-term extension of the kept support) is fitted with the physics for at most SCREEN_NFEV evaluations, and the
#: SCREEN that fit the training records best are refitted in full.
SCREEN, SCREEN_NFEV = 4, 10


#: Significant digits to which the search compares mismatches and criteria (:func:`_settled`).
SETTLED_DIGITS = 5


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
    the library's order puts the plainer spelling first. The cosines come from one Gram matrix of ``indices``' columns:
    column by column against those kept, the two-mass chain's 912 terms on 24 000 samples took 146 s, silent."""
    if not indices:
        return []
    selected = unit[:, indices]
    cosines = (selected.T @ selected).abs()  # (len(indices), len(indices))
    kept: list[int] = []  # positions in indices
    for j in range(len(indices)):
        if not kept or float(cosines[kept, j].max()) < 1 - DUPLICATE:
            kept.append(j)
    return [indices[j] for j in kept]


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


@dataclass
class Regressed:
    """The sparse regression on the responses: the ``pairs`` regressed on, the indices of those ``usable`` (beyond
    what the physics or an earlier term makes), the regression's support (``proposed``), and ``Q``, the directions of
    the physics' unit-scaled Jacobian that the records determine."""

    pairs: list[Pair]
    usable: list[int]
    proposed: list[Pair]
    Q: torch.Tensor

    @classmethod
    def of(cls, data: Columns, pairs: list[Pair], regression: SparseRegression) -> Regressed:
        J = data.jacobian
        U, S, _ = torch.linalg.svd(J / J.norm(dim=0).clamp_min(1e-300), full_matrices=False)
        Q = U[:, S * COLLINEARITY_LIMIT >= 1]  # what the physics makes by moves the records determine
        log.debug("discovery: the physics' unit-scaled Jacobian has singular values %s; %d of them at least 1/%g",
                  [f"{v:.4g}" for v in S.tolist()], Q.shape[1], COLLINEARITY_LIMIT)

        def projected(M: torch.Tensor) -> torch.Tensor:
            return M - Q @ (Q.T @ M)

        columns = projected(data.responses)
        norms = columns.norm(dim=0)
        usable = _distinct([i for i in range(len(pairs)) if norms[i] > 1e-3 * data.responses[:, i].norm()],
                           columns / norms.clamp_min(1e-300))  # the rest the physics makes, or an earlier term does
        support = regression.select(columns[:, usable] / norms[usable], projected(data.measured[:, None])[:, 0],
                                    [projected(data.learned[:, None])[:, 0]])
        return cls(pairs, usable, [pairs[usable[i]] for i in support], Q)


class ClosedFormSearch:
    """The regression's support refitted; where its first-order form does not hold, or rests on a physics the records
    do not determine, the screened single terms compete with it, then one more term at a time (:meth:`best`).
    ``undecided`` names the forms a budget stopped."""

    def __init__(self, ranking: Ranking, library_best: EffectEvidence | None, train: Sequence[Record],
                 validation: Sequence[Record], data: Columns, regressed: Regressed, max_nfev: int, limits: Budget):
        self.baseline, self.rule, self.initial_state = ranking.baseline, ranking.rule, ranking.initial_state
        self.library_best, self.train, self.validation = library_best, train, validation
        self.data, self.regressed, self.max_nfev = data, regressed, max_nfev
        self.limits = limits  # each refit's (:mod:`torchpaml._budget`), restarted for each; a screen takes its share
        self.undecided: list[str] = []

    def first_order(self, kept: list[Pair]) -> list[float] | None:
        """The coefficients of ``kept`` by least squares on the responses (with the physics' Jacobian), or ``None``
        where a term is not among the regressed ones (a limit replaced it)."""
        pairs, J = self.regressed.pairs, self.data.jacobian
        if any(p not in pairs for p in kept):
            return None
        columns = torch.cat([J, self.data.responses[:, [pairs.index(p) for p in kept]]], dim=1)
        return torch.linalg.lstsq(columns, self.data.measured[:, None]).solution[J.shape[1]:, 0].tolist()

    def refitted(self, kept: list[Pair]) -> Judged:
        """The closed form of ``kept`` refitted, whether it is missing (:func:`_judge`) and why."""
        form = ", ".join(f"{t} ({e})" for e, t in kept)
        budget = self.limits.restarted(f"discovery: refitting {form}")
        log.info("discovery: refitting %s (at most %s)", form, budget.describe())
        try:
            score = refit_closed_form(self.baseline.model, kept, self.first_order(kept), self.data.widths, self.train,
                                      self.validation, self.rule, self.max_nfev, self.initial_state, self.first_order,
                                      budget, self.baseline.solver)
        except OverBudget as over:
            self.undecided.append(f"{form}: over budget ({over.seconds:.1f} s)")
            return None, None, f"its refit stopped over budget ({over.seconds:.1f} s)"
        if score is None:
            return None, None, "no term of the closed form is determined by the records"
        return score, *_judge(self.baseline, self.library_best, score, self.rule)

    def screened(self, base: list[Pair], starts: list[float]) -> list[Judged]:
        """``base`` (fitted coefficients ``starts``) plus each usable term not in it, fitted with the physics for
        :data:`SCREEN_NFEV` evaluations; the :data:`SCREEN` that fit the training records best, refitted in full."""
        pairs, proposed, short = self.regressed.pairs, self.regressed.proposed, {}
        extras = [pairs[i] for i in self.regressed.usable
                  if pairs[i] not in base and base + [pairs[i]] != proposed]  # refitted already
        for i, extra in enumerate(extras, 1):
            budget = self.limits.restarted(f"discovery: screening {extra[1]}", SCREEN_NFEV / self.max_nfev)
            if budget.expired:
                self.undecided.append(f"the screen beside [{', '.join(t for _, t in base)}]: the diagnosis' budget "
                                      f"was spent after {i - 1} of {len(extras)} terms")
                break
            kept = base + [extra]
            log.info("discovery: screening %d of %d: %s (%s)", i, len(extras), extra[1], extra[0])
            try:
                fitted = fit_closed_form(self.baseline.model, kept, self.first_order(kept) or [*starts, 0.0],
                                         self.data.widths, self.train, SCREEN_NFEV, self.initial_state, budget,
                                         self.baseline.solver)
            except OverBudget as over:
                self.undecided.append(f"{', '.join(t for _, t in kept)}: screen over budget ({over.seconds:.1f} s)")
                continue
            if fitted is not None:
                short[extra] = fitted[1].mismatch
        ordered = sorted(short, key=lambda extra: _settled(short[extra]))  # ties: the library's order
        log.debug("discovery: screened mismatches %s", [(f"{short[e]:.6g}", e[1], e[0]) for e in ordered[:2 * SCREEN]])
        return [self.refitted(base + [extra]) for extra in ordered[:SCREEN]]

    def best(self, max_terms: int) -> Judged:
        """The best closed form: the regression's support refitted, and, where first order may be misled, the
        screened forms, grown one term at a time (at most ``max_terms``) while that beats the threshold."""
        candidates = [self.refitted(self.regressed.proposed)]
        # a combination of the physics' parameters that the records do not determine
        sloppy = self.regressed.Q.shape[1] < self.data.jacobian.shape[1]
        search = candidates[0][1] is None or sloppy  # first order may be misled: a search by refits
        if search:
            log.info("discovery: the first-order closed form %s; screening %d single terms",
                     "rests on a physics the records do not determine" if sloppy else "does not hold",
                     len(self.regressed.usable))
            candidates += self.screened([], [])
        held = [c for c in candidates if c[1] is not None]
        best = min(held, key=lambda c: _settled(c[0].criterion)) if held else candidates[0]
        while search and best[1] is not None and len(support := _support(best[0])) < max_terms:
            log.info("discovery: screening one more term beside %s", ", ".join(t for _, t in support[0]))
            extended = [c for c in self.screened(*support) if c[1] is not None]  # forward, one term at a time
            top = min(extended, key=lambda c: _settled(c[0].criterion), default=None)
            if top is None or top[0].criterion >= best[0].criterion - self.rule.threshold:
                break
            best = top
        return best
