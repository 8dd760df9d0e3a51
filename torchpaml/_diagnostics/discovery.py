r"""Discover a missing force that is not in the library: a neural force in the ODE, then a closed form.

:func:`discover_missing_force` runs on the baseline of a ranking (the ladder's first rung), the
physics alone at its fitted parameters $\hat\theta$ (linear second-order physics, $\ddot x = a_{\hat\theta}(x, v, u)$, $y = x$):

1. **Neural force** (a universal differential equation, :func:`~torchpaml._fit.fit_neural_force`):
   $\ddot x = a_{\hat\theta} + \mathrm{MLP}(x, v, u)$, the physics held, fitted by output error.
   Its trajectory gives the states $x_k, v_k$ that the records do not measure.
2. **Closed form.** Along that trajectory every library term $\theta_i(x_k, v_k, u_k)$
   (:func:`~torchpaml._physics.discovered.candidate_terms`) and every physics sensitivity
   $\partial a/\partial\theta_j$ is passed through the physics' own force-to-output response
   $\mathcal L = C(sI - A)^{-1}e_v$ (the exact LTI path), so that terms are compared by what they do
   to the output, where the records can tell them apart (a force at frequencies the physics filters
   out is invisible, whatever its size). The learned force, seen the same way, is
   $\mathcal L[\mathrm{MLP}] = \hat y_{\text{neural}} - \hat y_{\text{physics}}$. What the physics'
   own parameters can produce is projected out (the first-order incompatibility of Kuang & Lin), and
   sparse regression (:func:`~torchpaml._fit.sparse_regression.select_support`: STLSQ, SINDy's method,
   plus a forward path) picks the few terms of lowest BIC against the measured residual
   $y - \hat y_{\text{physics}}$, with the learned force's STLSQ path among the proposals.
   The regression sees the terms to first order (through the physics' linear response), so it may
   keep a few small ones that only mop up the nonlinearity's own feedback.
3. **Refit and rank.** The closed form becomes a :class:`~torchpaml._physics.DiscoveredForce`, refitted
   by output error with the physics (:func:`~torchpaml._fit.fit_physics`: coefficients, the width of
   a smoothed sign, and the physics' parameters). Terms whose share of the refitted force along the
   trajectory is below :data:`PRUNE` are then dropped and the rest refitted, unless that costs more
   than ``threshold`` of the criterion. The closed form is scored on the validation records like every
   rung. It is **recommended** when it beats the physics by the ranking's rules (criterion gain above
   ``threshold``, validation mismatch down by ``min_share``, training mismatch not worse) *and* beats
   the best library effect's criterion by more than ``threshold``; otherwise the library effect,
   which has a physical meaning and a name, is preferred. A closed form that does not beat the
   physics means that nothing is missing: the expression is ``"0"``.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import torch

from torchpaml._data import Experiment
from torchpaml._diagnostics.ranking import EffectEvidence, ModelScore, Ranking, as_records, refit_effect, score_model
from torchpaml._fit.neural_force import fit_neural_force
from torchpaml._fit.sparse_regression import select_support
from torchpaml._metrics import mismatch
from torchpaml._physics.base import SecondOrderPhysics
from torchpaml._physics.discovered import DiscoveredForce, candidate_terms, evaluate_term
from torchpaml._simulate.lti import simulate_lti
from torchpaml._simulate.sensitivity import simulate_record
from torchpaml._simulate.shooting import simulate_rk4
from torchpaml._simulate.simulator import uniform_step

__all__ = ["Discovery", "discover_missing_force", "why_discovery_cannot_run"]

#: Width of the library's smoothed sign tanh(v/eps) in the regression (the Coulomb effect's); the refit frees it.
SIGN_WIDTH = 0.01
#: A term of the refitted closed form whose force is below this share of the largest term's is dropped.
PRUNE = 0.05
#: Relative central-difference step of the acceleration's parameter sensitivities.
STEP = 1e-6


@dataclass
class Discovery:
    """What :func:`discover_missing_force` found (module docstring); :func:`~torchpaml.discovery_to_dict` makes ``discovery.json``.

    ``effect`` is the refitted closed form (``None`` when the regression kept no term); ``samples``
    holds x, v, u, the learned force and the closed form's force (with the physics' correction)
    along the first training record's neural trajectory, for :meth:`figure`.
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

    @property
    def expression(self) -> str:
        return "0" if self.effect is None else self.effect.expression()


def _sensitivities(physics, names: list[str], x: torch.Tensor, v: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    r"""$\partial a/\partial\theta_j$ at the samples, (samples, parameters), by central differences in $\theta_j$."""
    t = torch.zeros_like(x)
    columns = []
    values = physics.physical_parameters()
    with torch.no_grad():
        for name in names:
            step = STEP * max(1.0, abs(values[name]))
            physics.assign(**{name: values[name] + step})
            plus = physics.acceleration(t, x, v, u)
            physics.assign(**{name: values[name] - step})
            minus = physics.acceleration(t, x, v, u)
            physics.assign(**{name: values[name]})
            columns.append((plus - minus) / (2 * step))
    return torch.stack(columns, dim=1) if columns else torch.zeros(len(x), 0, dtype=x.dtype)


def _through_output(physics, record: Experiment, forces: torch.Tensor) -> torch.Tensor:
    r"""Each column of ``forces`` (samples, k) applied as a force from rest and seen at the output: $\mathcal L[F]$."""
    A, _, C, _ = (m.detach() for m in physics.state_space())
    e_v = torch.tensor([[0.0], [1.0]], dtype=A.dtype)
    responses = simulate_lti(A, e_v, C, torch.zeros(C.shape[0], 1, dtype=A.dtype), uniform_step(record.t),
                             forces.T[:, :, None])
    return responses[:, :, 0].T


def _along_trajectories(neural, physics, names: list[str], terms: list[str], train: Sequence[Experiment],
                        starts: Sequence[torch.Tensor]) -> tuple[torch.Tensor, ...]:
    r"""Along the neural model's trajectories, records concatenated: $\mathcal L$ of the library terms
    (samples, terms), of the sensitivities $\partial a/\partial\theta$ (samples, parameters) and of the learned
    force (samples,); the measured residual $y - \hat y_{\text{physics}}$ (samples,); and the first record's
    raw samples (x, v, u, learned, library, sensitivity) for the figure."""
    parts: dict[str, list[torch.Tensor]] = {key: [] for key in ("library", "sensitivity", "learned", "measured")}
    samples: dict[str, torch.Tensor] = {}
    with torch.no_grad():
        for record, x0 in zip(train, starts, strict=True):
            states = simulate_rk4(neural, record.t - record.t[0], record.u[None], x0.reshape(1, -1),
                                  hold=record.hold)[0]
            x, v, u = states[:, 0], states[:, 1], record.u[:, 0]
            raw = {"library": torch.stack([evaluate_term(term, x, v, u, SIGN_WIDTH) for term in terms], dim=1),
                   "sensitivity": _sensitivities(physics, names, x, v, u), "learned": neural.force(x, v, u)[:, None]}
            for key, value in raw.items():
                parts[key].append(_through_output(physics, record, value))
            parts["measured"].append((record.y - simulate_record(physics, record, x0)[0])[:, 0])
            samples = samples or {"x": x, "v": v, "u": u, **raw, "learned": raw["learned"][:, 0]}
    library, sensitivity, learned, measured = (torch.cat(parts[k]) for k in ("library", "sensitivity", "learned",
                                                                               "measured"))
    return library, sensitivity, learned[:, 0], measured, samples


def why_discovery_cannot_run(physics) -> str | None:
    """Why discovery does not apply to ``physics``, or ``None`` when it does (linear second-order physics)."""
    if isinstance(physics, SecondOrderPhysics) and physics.state_space() is not None:
        return None
    return (f"discovery needs linear second-order physics (a SecondOrderPhysics with state_space()), got "
            f"{getattr(physics, 'display_name', type(physics).__name__)}: the learned force is compared with the "
            "library terms through the physics' own force-to-output response. Diagnose the linear part, or add "
            "effects from the library")


def discover_missing_force(
    ranking: Ranking,
    train: Experiment | Sequence[Experiment],
    validation: Experiment | Sequence[Experiment],
    *,
    criterion: Literal["bic", "aic"] = "bic",
    threshold: float = 10.0,
    min_share: float = 0.05,
    initial_state: Literal["rest", "estimate"] = "rest",
    max_terms: int = 4,
    max_iter: int = 60,
    max_nfev: int = 40,
    seed: int = 0,
) -> Discovery:
    """Discover the force missing from the ladder's physics (module docstring).

    Args:
        ranking: the library's ranking on the physics (:func:`~torchpaml._diagnostics.rank_missing_effects`,
            the ladder's first): its baseline is the fitted physics, its best refitted physical entry the
            library's best effect.
        train: the training record(s) the ranking was made on.
        validation: the validation record(s) the ranking was made on.
        criterion: as in :func:`~torchpaml._diagnostics.rank_missing_effects`.
        threshold: as in :func:`~torchpaml._diagnostics.rank_missing_effects`.
        min_share: as in :func:`~torchpaml._diagnostics.rank_missing_effects`.
        initial_state: as in :func:`~torchpaml._diagnostics.rank_missing_effects`.
        max_terms: most terms in the closed form.
        max_iter: L-BFGS iterations of the neural force.
        max_nfev: iteration limit of the closed form's refit.
        seed: seed of the network's initial weights.
    """
    train, validation = as_records(train), as_records(validation)
    baseline = ranking.baseline
    physics = baseline.model
    reason = why_discovery_cannot_run(physics)
    if reason is not None:
        raise ValueError(reason)
    for record in train:
        uniform_step(record.t)  # the force-to-output response is the exact (uniform-grid) path
    neural = fit_neural_force(physics, train, baseline.train_states, max_iter=max_iter, seed=seed)
    with torch.no_grad():
        neural_validation = mismatch(torch.cat([r.y for r in validation]),
                                     torch.cat([simulate_record(neural.model, r, x0)[0]
                                                for r, x0 in zip(validation, baseline.validation_states, strict=True)]))
    terms = candidate_terms()
    names = physics.learnable_names()
    library, sensitivity, learned, measured, samples = _along_trajectories(neural.model, physics, names, terms, train,
                                                                           baseline.train_states)
    Q = torch.linalg.qr(sensitivity).Q if names else sensitivity

    def projected(M: torch.Tensor) -> torch.Tensor:
        return M - Q @ (Q.T @ M)

    columns = projected(library)
    norms = columns.norm(dim=0)
    usable = [i for i in range(len(terms)) if norms[i] > 1e-6 * library[:, i].norm()]  # the rest the physics makes
    support, _ = select_support(columns[:, usable] / norms[usable], projected(measured[:, None])[:, 0],
                                [projected(learned[:, None])[:, 0]], max_terms)
    chosen = [usable[i] for i in support]
    library_best = next((e for e in ranking.entries if e.refit is not None and not e.unphysical), None)
    physics_only = torch.linalg.lstsq(sensitivity, measured[:, None]).solution[:, 0] if names else torch.zeros(0)
    if not chosen:
        samples["closed_form"] = samples["sensitivity"] @ physics_only
        return Discovery(baseline, library_best, neural.mismatch, neural_validation, None, None, False,
                         "the sparse regression kept no term: nothing is missing that the physics cannot make", samples)
    joint = torch.linalg.lstsq(torch.cat([sensitivity, library[:, chosen]], dim=1), measured[:, None]).solution[:, 0]
    correction, coefficients = joint[: len(names)], joint[len(names):]
    samples["closed_form"] = samples["library"][:, chosen] @ coefficients + samples["sensitivity"] @ correction
    discovered = _refit_and_prune(physics, [terms[i] for i in chosen], coefficients.tolist(),
                                  samples["library"][:, chosen], train, validation, criterion, threshold, max_nfev,
                                  initial_state)
    effect = discovered.model.effects["discovered"]
    missing, reason = _judge(baseline, library_best, discovered, threshold, min_share)
    if missing is None:  # the closed form does not improve on the physics: nothing is missing
        samples["closed_form"] = samples["sensitivity"] @ physics_only
        return Discovery(baseline, library_best, neural.mismatch, neural_validation, None, None, False,
                         f"the best closed form, {effect.expression()}, does not improve on the physics: {reason}", samples)
    return Discovery(baseline, library_best, neural.mismatch, neural_validation, effect, discovered, missing, reason,
                     samples)


def _refit_and_prune(physics, terms: list[str], coefficients: list[float], values: torch.Tensor,
                     train: Sequence[Experiment], validation: Sequence[Experiment], criterion: str, threshold: float,
                     max_nfev: int, initial_state: str) -> ModelScore:
    """``physics + DiscoveredForce(terms)`` refitted and scored; then without the terms whose force (``values``,
    (samples, terms), times the refitted coefficient) is below :data:`PRUNE` of the largest, unless that costs
    more than ``threshold`` of the criterion."""

    def refit(kept: list[str], start: list[float]) -> ModelScore:
        extended = copy.deepcopy(physics) + DiscoveredForce(kept, start, eps=SIGN_WIDTH)
        estimate = refit_effect(extended, "discovered.gain", 1.0, train, max_nfev, initial_state)
        return score_model(extended, estimate, validation, criterion, initial_state)

    full = refit(terms, coefficients)
    fitted = [c for _, c in full.model.effects["discovered"].terms_and_coefficients()]
    sizes = (values * torch.tensor(fitted)).norm(dim=0).tolist()
    kept = [(t, c) for t, c, size in zip(terms, fitted, sizes, strict=True) if size >= PRUNE * max(sizes)]
    if len(kept) == len(terms):
        return full
    pruned = refit([t for t, _ in kept], [c for _, c in kept])
    return pruned if pruned.criterion <= full.criterion + threshold else full


def _judge(physics: ModelScore, library: EffectEvidence | None, discovered: ModelScore, threshold: float,
           min_share: float) -> tuple[bool | None, str]:
    """``(None, why)`` when the closed form does not improve on the physics; else whether it is recommended
    over the best library effect, and why."""
    gain = physics.criterion - discovered.criterion
    share = 1 - discovered.nrmse_validation / physics.nrmse_validation
    if discovered.nrmse_train > physics.nrmse_train * (1 + 1e-6):
        return None, "its refit ended above the physics' training mismatch (a failed optimisation)"
    if gain <= threshold or share < min_share:
        return None, (f"it changes the criterion by {gain:+.1f} (needed more than {threshold:g}) and the validation "
                      f"mismatch by {100 * share:.1f} % (needed {100 * min_share:g} %)")
    if library is not None:
        margin = library.refit.criterion - discovered.criterion
        if margin <= threshold:
            return False, (f"the library effect {library.effect} explains the records as well (criterion "
                           f"{margin:+.1f} against it, needed more than {threshold:g}): the named effect is preferred")
        return True, f"it beats the physics by {gain:.1f} and the best library effect ({library.effect}) by {margin:.1f}"
    return True, f"it beats the physics by {gain:.1f}; no library effect was refitted"
