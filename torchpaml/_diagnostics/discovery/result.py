r"""Discover what is missing outside the library: a neural rate in the ODE, then a closed form.

:func:`discover_missing_force` runs on a ranking's baseline (the ladder's last rung): any physics at
its fitted parameters $\hat\theta$, $\dot x = f_{\hat\theta}(t, x, u)$, $y = h(x, u)$.

1. **Neural rate** (a universal differential equation, :func:`~torchpaml.fit_neural_force`):
   $\dot x = f_{\hat\theta} + E\,\mathrm{MLP}(x, u)$, the physics held, fitted by output error. $E$ picks
   the equations a term may enter (:func:`~torchpaml._physics.terms.variables_of`): the acceleration of
   second-order physics, every state's rate otherwise. Its trajectory gives the states that the
   records do not measure.
2. **Closed form.** Along that trajectory every term $\theta_i$ of the library
   (:class:`~torchpaml.TermLibrary`) on every equation $e$ is passed through the physics'
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
3. **Refit, with honest numbers** (:func:`~torchpaml._diagnostics.discovery.closed_form.refit_closed_form`). The
   closed form becomes a :class:`~torchpaml.DiscoveredForce` refitted with the physics by
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

from dataclasses import dataclass, field

import torch

from torchpaml._diagnostics.results import EffectEvidence, ModelScore, Ranking
from torchpaml._physics.discovered import DiscoveredForce
from torchpaml._physics.terms import compile_term

__all__ = ["Discovery", "closed_form_samples", "library_best"]



@dataclass
class Discovery:
    """What :func:`discover_missing_force` found (module docstring); :func:`~torchpaml.discovery_to_dict` makes ``discovery.json``.

    ``effect`` is the refitted closed form (``None`` when nothing was kept); ``samples`` holds, along the
    first training record's neural trajectory, each variable, and the learned rate and the closed form's
    rate on the first equation, for :func:`~torchpaml.discovery_figure`. ``undecided`` names the forms whose fit
    stopped over its budget (:mod:`torchpaml._budget`), a neural rate that stopped over its budget, and a search that
    the diagnosis' budget ended. ``searched`` is false where nothing was searched (the physics was complete:
    :meth:`~torchpaml.Discoverer.discover`); then the neural figures are ``None``.
    """

    physics: ModelScore
    library_best: EffectEvidence | None
    neural_train: float | None
    neural_validation: float | None
    effect: DiscoveredForce | None
    discovered: ModelScore | None
    recommended: bool
    reason: str
    samples: dict[str, torch.Tensor] = field(repr=False)
    undecided: list[str] = field(default_factory=list)
    searched: bool = True
    #: the ladder's effects this form, found on the physics alone, replaces: they stood in for it
    #: (:func:`~torchpaml._diagnostics.diagnosis.diagnose`, step 4); empty where it extends the last rung
    replaces: list[str] = field(default_factory=list)

    @property
    def expression(self) -> str | dict[str, str]:
        return "0" if self.effect is None else self.effect.expression()

    @property
    def text(self) -> str:
        """The expression on one line: ``"equation: expression; ..."`` for several equations."""
        found = self.expression
        return found if isinstance(found, str) else "; ".join(f"{k}: {v}" for k, v in found.items())


def library_best(ranking: Ranking) -> EffectEvidence | None:
    """The ranking's best refitted physical candidate: what a discovered form must beat to be recommended."""
    return next((e for e in ranking.entries if e.refit is not None and not e.unphysical), None)


def closed_form_samples(effect: DiscoveredForce, samples: dict[str, torch.Tensor], variables: tuple[str, ...],
                         equation: str) -> torch.Tensor:
    """The closed form's rate on ``equation`` at the figure's samples."""
    values = {**{v: samples[v] for v in variables}, **{w: getattr(effect, w).detach() for w in effect.width_names}}
    total = torch.zeros_like(samples["learned"])
    for name, term, eq in zip(effect.parameter_names, effect.terms, effect.equations, strict=True):
        if eq == equation:
            total = total + float(getattr(effect, name).detach()) * compile_term(term, None).evaluate(values)
    return total * float(effect.gain.detach())


