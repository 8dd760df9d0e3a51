r"""The first-order score of a candidate effect (the ranking's step 2, :mod:`~torchpaml._diagnostics.ranking.steps`): the
share of the residual that the effect's output direction, beyond what the physics' own parameters make, removes."""

from __future__ import annotations

import copy
import functools

import torch
from torch import nn

from torchpaml._data import Record
from torchpaml._diagnostics.ranking.probes import Secant, TangentLinear
from torchpaml._errors import ConfigurationError
from torchpaml._fit.physics_fit import PhysicsEstimate
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effects import AbstractEffect

__all__ = ["ACTING", "MIN_ACTING_SHARE", "NULL_COLUMN", "NULL_DIRECTION", "Engines", "acting_share", "beyond_physics",
           "by_promise", "first_order", "physics_step", "share"]

#: A sample's output moves under a probe where its change exceeds this share of the largest change.
ACTING = 1e-9
#: A candidate whose probe moves fewer than this share of the training samples is not judged by its first-order
#: score (a clip whose level the fitted output barely reaches: whether it reaches it is a detail of rounding).
MIN_ACTING_SHARE = 0.05

#: A direction of the physics' unit-scaled Jacobian whose singular value is below this share of the largest is
#: numerically null (:func:`_determined`).
NULL_DIRECTION = 1e-10
#: A column of the physics' Jacobian whose norm is below this share of the largest column's is a parameter that does
#: not move the output (:func:`_determined`): a central difference's rounding is about 1e-10 of the output's scale.
NULL_COLUMN = 1e-8


class Engines:
    """The probe engine for each candidate, each built once, with the base's own output it computes (the
    reference of the zero-strength check): the tangent-linear model around a linear base for an effect
    without states of its own, else secants by the fixed-step solver the base was fitted with."""

    def __init__(self, base: AbstractPhysics, train: list[Record], fit: PhysicsEstimate, scale: torch.Tensor):
        self.base, self.train, self.initial_states, self.scale = base, train, fit.initial_states, scale
        self.solver = fit.solver
        self.built: dict[str, tuple[TangentLinear | Secant, torch.Tensor] | None] = {}

    def of(self, effect: AbstractEffect) -> tuple[TangentLinear | Secant, torch.Tensor]:
        kind = "secant" if effect.own_states else "linear"
        if kind == "linear" and kind not in self.built:
            self.built[kind] = self._with_reference(TangentLinear.of(self.base, self.train, self.initial_states))
        if self.built.get(kind) is None:
            kind = "secant"
            if kind not in self.built:
                self.built[kind] = self._with_reference(Secant(self.base, self.train, self.initial_states,
                                                                              self.solver))
        return self.built[kind]

    def _with_reference(self, engine):
        return None if engine is None else (engine, engine.outputs(self.base) / self.scale)


@functools.lru_cache(maxsize=1)  # one rung's Jacobian, decomposed once for every candidate's probes (a tensor hashes by id)
def _determined(J: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""The directions of the physics' unit-scaled Jacobian that are not numerically null: $J D^{-1} = U S V^\top$
    ($D$ the columns' norms) truncated to the singular values of at least :data:`NULL_DIRECTION` times the largest.
    Returns $U_k$ (samples, k), $S_k$, $V_k^\top$ (k, unknowns) and $D$.

    A parameter that does not move the output (one at the limit of its constraint) or an exact degeneracy leaves a
    singular value at the rounding level (1e-18 on the cascaded tanks' third rung), and a least squares of the full
    $J$ keeps or drops that direction by its last digits, which move with the process's memory layout: there, runs
    with PYTHONHASHSEED 0 and 1 scored the same candidate 0.61 and 0.35 and climbed different ladders. Cut at
    1e-10, both score 0.73.

    A column below :data:`NULL_COLUMN` of the largest column's norm is such a parameter too, and is left out before
    the scaling: its entries are the rounding of a central difference (0 on one copy of the cascaded tanks' records,
    2.8e-12 on the same records perturbed by 1e-12, where the other columns are 7e-3 to 2.2), which the scaling to a
    unit norm would make a direction like any other. Kept, it moved that rung's first-order scores by 20 to 60 % and
    the ladder to another end."""
    norms = J.norm(dim=0)
    scale = norms.clamp_min(1e-300)
    moving = norms > NULL_COLUMN * norms.max() if J.shape[1] else norms > 0
    U, S, Vh = torch.linalg.svd(torch.where(moving, J / scale, 0.0), full_matrices=False)
    keep = S >= NULL_DIRECTION * S[0] if len(S) else S > 0
    return U[:, keep], S[keep], Vh[keep], scale


def physics_step(J: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    r"""$-J^+ v$ (unknowns,): the Gauss-Newton step of the physics' own unknowns that removes ``v`` (samples,), by the
    pseudo-inverse of :func:`_determined`'s directions (none along a numerically null one)."""
    U, S, Vh, scale = _determined(J)
    return -(Vh.T @ ((U.T @ v) / S)) / scale


def beyond_physics(d: torch.Tensor, J: torch.Tensor) -> tuple[torch.Tensor, float]:
    r"""$\tilde d = (I - U_k U_k^\top) d$, the part of the output direction ``d`` (samples,) that the physics' own
    parameters (``J``'s columns, :func:`_determined`) cannot make, and its energy $\|\tilde d\|^2$."""
    Q = _determined(J)[0]
    projected = d - Q @ (Q.T @ d)
    return projected, float(projected @ projected)


def share(projected: torch.Tensor, energy: float, r: torch.Tensor) -> float:
    r"""The share of the residual's energy that a step along ``projected`` removes,
    $(\tilde d^\top r)^2 / (\|\tilde d\|^2 \|r\|^2)$."""
    return float(projected @ r) ** 2 / (energy * float(r @ r))


def first_order(extended: AbstractPhysics, name: str, fit: PhysicsEstimate, scale: torch.Tensor, probe: float,
                 reference: torch.Tensor, engine: TangentLinear | Secant
                 ) -> tuple[float, int, float, torch.Tensor, float]:
    r"""(score, order q, first-order strength, move, acting share) of the effect whose strength parameter is ``name``
    (module docstring).

    The acting share (:func:`acting_share`) is the share of the training samples whose output the probe moves: an
    effect that acts on few of them at the fitted model (a clip whose level the output barely reaches) has a score
    that a detail of rounding decides, and the ranking does not judge it by that score.

    The strength is probed at 0, δ, 2δ and -δ. An effect that moves the output the same way at ±δ
    (second order, or an absolute value such as the dead zone's |d|) can only add a positive multiple
    of its direction, so a negative coefficient scores 0.

    ``move`` (unknowns,) is the rest of the Gauss-Newton step from the baseline, for the physics' own
    unknowns (``fit.jacobian``'s columns): with the effect's output change $\beta d_c$ at the first-order
    strength, $\Delta\rho = -J^+(r - \beta d_c)$. The refit starts from both (:func:`refit_effect`).
    """
    outputs = [None if out is None else out / scale
               for out in engine.probes(extended, name, (0.0, probe, 2 * probe, -probe))]
    if outputs[0] is None:
        raise ConfigurationError(f"{name!r} cannot be 0, but an effect's strength parameter must switch it off at 0; "
                         "give it a constraint that allows 0 (e.g. Real())")
    extended.assign(**{name: 0.0})
    outputs = [out if out is not None else outputs[0] for out in outputs]
    off = float(torch.linalg.vector_norm(outputs[0] - reference) / torch.linalg.vector_norm(reference))
    if off > 1e-3:
        raise ConfigurationError(
            f"effect {name.partition('.')[0]!r} changes the model at zero strength (by {100 * off:.2g} % of the "
            f"output); its strength parameter {name!r} must switch the effect off at 0. Rewrite the effect so that "
            "its first declared parameter scales it"
        )
    d1, d2, d_minus = (outputs[i] - outputs[0] for i in (1, 2, 3))
    size = float(torch.linalg.vector_norm(d1))
    J, r = fit.jacobian, fit.residual
    still = torch.zeros(J.shape[1], dtype=J.dtype)
    if size == 0.0:
        return 0.0, 1, 0.0, still, 0.0  # the effect does not act on this record
    acting = acting_share(d1)
    order = 2 if float(torch.linalg.vector_norm(d2)) / size > 2**1.5 else 1
    one_sided = float(torch.linalg.vector_norm(d_minus - d1)) < 0.5 * size
    projected, energy = beyond_physics(d1, J)
    if energy <= 1e-20 * size**2:
        return 0.0, order, 0.0, still, acting  # the physics' own parameters already make this move
    beta = float(projected @ r) / energy
    if one_sided and beta <= 0:
        return 0.0, order, probe, still, acting
    score = share(projected, energy, r)
    move = physics_step(J, r - beta * d1)
    return score, order, probe * (beta if order == 1 else beta ** (1 / order)), move, acting


def acting_share(d: torch.Tensor) -> float:
    """The share of the samples of the output change ``d`` (samples,) that move by more than :data:`ACTING` of its
    largest: where the effect acts (the simulations' rounding elsewhere lies far below)."""
    largest = float(d.abs().max())
    return 0.0 if largest == 0.0 else float((d.abs() > ACTING * largest).double().mean())


def by_promise(base, candidate: AbstractEffect, train: list[Record], fit: PhysicsEstimate, delta: float,
                reference: torch.Tensor, engine: TangentLinear | Secant, scale: torch.Tensor) -> list[tuple[dict[str, float], nn.Module]]:
    r"""``(setting, base + candidate)`` for each of the candidate's starts (:meth:`~AbstractEffect.starts`), the most
    promising first: by the unsigned share of the residual that one probe at strength ``delta`` explains,
    $(\tilde d^\top r)^2 / (\|\tilde d\|^2 \|r\|^2)$ with $d$ taken against the base's output. One probe per start
    instead of :func:`first_order`'s four; a start whose probe blows up comes last."""
    name = f"{candidate.name}.{candidate.strength}"
    models = []
    for setting in candidate.starts(train):
        models.append((setting, (copy.deepcopy(base) + copy.deepcopy(candidate)).assign(
            **{f"{candidate.name}.{key}": value for key, value in setting.items()})))
    if len(models) == 1:
        return models

    def promise(model) -> float:
        out = engine.probes(model, name, (delta,))[0]
        if out is None:
            return -1.0
        projected, energy = beyond_physics(out / scale - reference, fit.jacobian)
        return 0.0 if energy == 0.0 else share(projected, energy, fit.residual)

    return sorted(models, key=lambda pair: -promise(pair[1]))
