"""The ranking's results: a fitted model's errors (:class:`ModelScore`), a candidate's evidence
(:class:`EffectEvidence`), and the ranking of the candidates (:class:`Ranking`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._fit.initial_state import InitialState, Rest
from torchpaml._fit.physics_fit import PhysicsEstimate
from torchpaml._parameters import with_uncertainty
from torchpaml._simulate.solvers import Auto, Solver

__all__ = ["EffectEvidence", "ModelScore", "Ranking"]


@dataclass
class ModelScore:
    """A fitted model's errors: mismatch (fraction) on training and validation, and the criterion on validation.

    It carries what scoring computed: the initial states of the training and validation records, each
    (n_state,), and the model's output on each validation record, (time, n_y), so that what is drawn or
    analysed later is the output that was scored; the solver the fit resolved (``PhysicsEstimate.solver``: pass
    it to simulate ``model`` as it was scored); and the 95 % ``interval`` of each fitted parameter.
    """

    name: str
    equation: str
    parameters: dict[str, float]
    nrmse_train: float
    nrmse_validation: float
    criterion: float
    model: torch.nn.Module = field(repr=False)
    uncertainty: dict[str, float] = field(default_factory=dict)
    warning: str | None = None
    train_states: list[torch.Tensor] = field(default_factory=list, repr=False)
    validation_states: list[torch.Tensor] = field(default_factory=list, repr=False)
    validation_outputs: list[torch.Tensor] = field(default_factory=list, repr=False)
    solver: Solver = field(default_factory=Auto, repr=False)
    interval: dict[str, tuple[float, float]] = field(default_factory=dict, repr=False)
    #: the fit scored (:class:`~torchpaml.PhysicsEstimate`): its residual and Jacobian start a ranking on this model
    estimate: PhysicsEstimate | None = field(default=None, repr=False)
    #: the validation samples the criterion counts (``0``: not given)
    samples: int = 0

    @property
    def fitted(self) -> FittedModel:
        """The scored model with its solver, one value that simulates a record as it was scored
        (``score.fitted.simulate(record)``)."""
        return FittedModel(self.model, self.solver)

    def rows(self) -> list[dict]:
        """The model's parameter rows (:func:`~torchpaml._parameters.describe_parameters`) with the fit's standard
        errors and 95 % intervals."""
        return with_uncertainty(self.model._rows(), self.uncertainty, self.interval)

    def describe(self) -> str:
        """The model's parameter table with the fit's standard errors and 95 % intervals
        (:meth:`~torchpaml.AbstractPhysics.describe`)."""
        return self.model.describe(_Spread(self.uncertainty, self.interval))


@dataclass(frozen=True)
class _Spread:
    """A fit's standard errors and intervals, as :meth:`~torchpaml.AbstractPhysics.describe` reads them."""

    std: dict[str, float]
    interval: dict[str, tuple[float, float]]


@dataclass
class EffectEvidence:
    """One candidate's evidence: its first-order score and, if refitted, its refitted model's errors.

    ``improvement`` is the baseline's criterion minus the candidate's (positive: better). ``failure``: why a
    shortlisted refit has no result (its optimum fails the step check, :mod:`torchpaml._fit.resolution`, or its
    simulation blows up: a lag driven towards 0 is a rate beyond what RK4 integrates), or why
    the candidate was not scored (its own states blow up at zero strength). ``refit_reason`` says why the
    candidate was or was not refitted; ``undecided`` is the seconds its refit ran before it stopped over its budget
    (:mod:`torchpaml._budget`; 0 where the diagnosis' budget was spent before it started), else ``None``;
    ``seconds`` the time its refit took (``None`` where it was not refitted); ``acting`` the share of the training
    samples whose output its first-order probe moves (:func:`~torchpaml._diagnostics.ranking.first_order.acting_share`).
    """

    effect: str
    equation: str
    score: float
    order: int
    first_order_strength: float
    refit: ModelScore | None = None
    improvement: float | None = None
    unphysical: list[str] = field(default_factory=list)
    failure: str | None = None
    refit_reason: str = ""
    undecided: float | None = None
    seconds: float | None = None
    acting: float = 1.0
    #: the effect's own states (:attr:`~torchpaml.AbstractEffect.own_states`), and whether it is generic
    #: (:attr:`~torchpaml.AbstractEffect.generic`): the simpler-effect rule (:mod:`~torchpaml._diagnostics.ranking.occam`)
    states: int = 0
    generic: bool = False


@dataclass
class Ranking:
    """The baseline and the candidates, best first (:mod:`~torchpaml._diagnostics.ranking.steps`), and the rule and
    initial-state policy they were ranked by (discovery on this ranking uses both)."""

    baseline: ModelScore
    entries: list[EffectEvidence]
    rule: SelectionRule = field(default_factory=SelectionRule)
    skipped: dict[str, str] = field(default_factory=dict)
    initial_state: InitialState = field(default_factory=Rest)
    #: the seconds after which the rung's fit stopped over its budget, its model keeping the parameters of the refit
    #: it comes from; ``None`` where it ended
    fit_over_budget: float | None = None
    #: the seconds of the rung's fit: of the physics on the first rung; on the next ones of the refit that found the
    #: added effect and of the fit from its optimum (the yardstick of the refits on this rung)
    fit_seconds: float | None = None
    #: why the first entry stands before a candidate of a lower criterion (the simpler-effect rule,
    #: :mod:`~torchpaml._diagnostics.ranking.occam`); ``None`` where the rule had no two kinds to weigh
    simpler: str | None = None
    #: the refitted candidates that give the first one's evidence (criteria within ``ranker.TIE``): the records
    #: cannot tell them apart on this physics (linear filters commute: an actuator and a sensor lag)
    equivalent: list[str] = field(default_factory=list)

    @property
    def recommended(self) -> EffectEvidence | None:
        """The best physical refitted candidate if :attr:`rule` accepts it over the baseline, else ``None``."""
        best = next((e for e in self.entries if e.refit is not None and not e.unphysical), None)
        return best if best is not None and self.rule.accepts(self.baseline, best.refit) else None

    @property
    def undecided(self) -> list[EffectEvidence]:
        """The candidates whose refit stopped over its budget: the ranking cannot tell whether they would win."""
        return [e for e in self.entries if e.undecided is not None]
