"""The effect protocol: :class:`AbstractEffect`, what ``physics + effect`` adds, and :class:`EffectState`, a state
an effect carries of its own. The library's effects: :mod:`~torchpaml._physics.effects`."""

from __future__ import annotations

import copy
from dataclasses import dataclass

import torch
from torch import nn

from torchpaml._arguments import Rebuildable

from torchpaml._errors import ConfigurationError
from torchpaml._parameters import copied_with_own_parametrizations
from torchpaml._physics.base import state_vector
from torchpaml._physics.composed import ComposedModel, compose

__all__ = ["AbstractEffect", "EffectState"]


@dataclass(frozen=True)
class EffectState:
    """A state an effect carries of its own (a hysteretic displacement, a lagged input): its name, unit and
    initial value. ``physics + effect`` appends it to the state vector as ``effect.name``."""

    name: str
    unit: str = "-"
    initial: float = 0.0
    meaning: str = ""


class AbstractEffect(Rebuildable, nn.Module):
    """An effect added to physics with ``+`` (module docstring). Override any of the four hooks:

    * ``force(physics, x, v, u)``: an extra acceleration (batch,) from x, v, u (batch,) of a mechanical degree of
      freedom, entering its velocity's equation (below);
    * ``rate(physics, x, u)``: an extra term of $\\dot x$, (batch, n_state) from x (batch, n_state) and
      u (batch, n_input), for any physics; :meth:`on_state` builds it for one named state equation;
    * ``input_map(u)`` and ``output_map(y)``: elementwise transforms of the signals, for any physics.

    Defaults: no force, no rate, identity maps. ``physics`` is the base model, for effects that scale
    with its parameters. :meth:`applies_to` says why an effect cannot be added to a physics.

    **Where a force acts.** A force acts on one mechanical degree of freedom of the physics
    (:attr:`~torchpaml.AbstractPhysics.degrees_of_freedom`, a (position, velocity) pair): ``force`` gets that
    position and velocity, its acceleration enters that velocity's equation, and an effect with memory sees the
    pair as the columns (position, velocity) of ``x`` in :meth:`state_rate`. By default the physics' only degree of
    freedom (``v`` of second-order physics); ``effect.on("v2")`` names another (:meth:`on`), and the ranking tries
    a force on each degree of freedom of a physics with several (:meth:`placements`).

    **Effects with memory** declare :attr:`own_states` (:class:`EffectState`) and give their dynamics in
    :meth:`state_rate`; the composed model integrates them with the physics. Their hooks then receive the
    effect's states ``z`` (batch, k) as one more, last argument: ``force(physics, x, v, u, z)``,
    ``rate(physics, x, u, z)``, ``input_map(u, z)``, ``output_map(y, z)``. At strength 0 the states may evolve but
    must not act.
    """

    name: str = ""
    equation: str = ""
    #: the state names the effect's ``rate`` needs in the base physics (checked by :meth:`applies_to`)
    states: tuple[str, ...] = ()
    #: fixed parameters that set the effect's shape (a smoothing width), which the ranking may free
    #: when the data asks for it (:func:`~torchpaml.rank_missing_effects`)
    shape: tuple[str, ...] = ()
    #: the effect's own states, appended to the physics' state vector (module docstring of ``composed``)
    own_states: tuple[EffectState, ...] = ()
    #: whether :meth:`output_map` also reads the measured input, as ``output_map(y, u=u)`` (a path from the input
    #: straight to the sensor); ``u`` then comes in the layout of ``y``, (..., n_u, batch)
    reads_input: bool = False
    #: whether :meth:`output_map` also reads the base physics' states, as ``output_map(y, x=x, physics=base)`` (an
    #: output map $h(x, u)$ of the states); ``x`` then comes in the layout of ``y``, (..., n_state, batch)
    reads_state: bool = False
    #: the velocity state a force acts on (:meth:`on`); ``None``: the physics' only degree of freedom
    acts_on: str | None = None
    #: a strength far from 0, at the end of its physical range, from which the probes of where the mismatch points
    #: also refit the effect on the physics alone (:class:`~torchpaml.Prober`): for an effect whose first-order
    #: direction at 0 is blind to it, and which the effects fitted in its place hide (a sensor that reads only the
    #: magnitude leaves the fitted linear physics almost no gain and a constant offset); ``None``: none
    far_strength: float | None = None
    #: a generic, flexible effect (a latent state, an extra mode, a quadratic sensor or input map, a saturation): it
    #: approximates almost any small mismatch, so it is a place more than physics. The ranking keeps it only where it
    #: beats every accepted physical candidate by the rule itself (:mod:`~torchpaml._diagnostics.ranking.occam`)
    generic: bool = False

    def __deepcopy__(self, memo: dict) -> AbstractEffect:
        """A copy that reads its own parameter values (:func:`~torchpaml._parameters.copied_with_own_parametrizations`)."""
        return copied_with_own_parametrizations(self, memo)

    @property
    def is_force(self) -> bool:
        """Whether the effect adds a force (it overrides :meth:`force`), which acts on a degree of freedom."""
        return type(self).force is not AbstractEffect.force

    def on(self, velocity: str) -> AbstractEffect:
        """A copy of this force acting on the degree of freedom whose velocity state is ``velocity``, named
        ``<name>_<velocity>`` (``CoulombFriction().on("v2")`` is ``coulomb_friction_v2``, its parameters
        ``coulomb_friction_v2.Fc``, ...)."""
        if not self.is_force:
            raise ConfigurationError(f"{self.name} is not a force: it acts where its own equations say, not on a "
                                     f"degree of freedom; add it as it is")
        if self.acts_on is not None:
            raise ConfigurationError(f"{self.name} already acts on {self.acts_on}; call on() on the effect itself")
        placed = copy.deepcopy(self)
        placed.acts_on, placed.name = velocity, f"{self.name}_{velocity}"
        placed.equation = f"{self.equation} on {velocity}"
        return placed

    def placements(self, physics: nn.Module) -> list[AbstractEffect]:
        """The effect on each degree of freedom of ``physics`` it may act on: one copy per velocity (:meth:`on`) for a
        force not yet placed on a physics with several; else the effect itself."""
        dofs = physics.degrees_of_freedom
        if not self.is_force or self.acts_on is not None or len(dofs) < 2:
            return [self]
        return [self.on(velocity) for _, velocity in dofs]

    def degree_of_freedom(self, physics: nn.Module) -> tuple[int, int]:
        """The indices of the (position, velocity) states of ``physics`` this force acts on."""
        dofs = physics.degrees_of_freedom
        pair = dofs[0] if self.acts_on is None else next(p for p in dofs if p[1] == self.acts_on)
        return physics.state_names.index(pair[0]), physics.state_names.index(pair[1])

    @property
    def strength(self) -> str:
        """The strength parameter: the first declared one. At strength 0 the effect must leave the model unchanged."""
        return next(iter(self._physical))

    def __radd__(self, physics) -> ComposedModel:
        """``physics + effect`` -> :class:`~torchpaml.ComposedModel` (:func:`~torchpaml._physics.composed.compose`);
        :class:`~torchpaml.ConfigurationError` where the effect does not apply."""
        return compose(physics, self)

    def applies_to(self, physics: nn.Module) -> str | None:
        """Why this effect cannot be added to ``physics`` (the base model), or ``None`` if it can."""
        if self.is_force:
            reason = self._placement_problem(physics)
            if reason is not None:
                return reason
        missing = [s for s in self.states if s not in physics.state_names]
        if missing:
            return (f"{self.name} acts on the state(s) {missing}, which {physics.display_name} does not have "
                    f"(its states: {list(physics.state_names)})")
        return None

    def _placement_problem(self, physics: nn.Module) -> str | None:
        dofs = physics.degrees_of_freedom
        if not dofs:
            return (f"{self.name} is a force, which acts on a mechanical degree of freedom; {physics.display_name} "
                    f"declares none (a SecondOrderPhysics has one; another physics lists its (position, velocity) "
                    f"state pairs in degrees_of_freedom)")
        velocities = [velocity for _, velocity in dofs]
        if self.acts_on is None and len(dofs) > 1:
            return (f"{self.name} is a force and {physics.display_name} has {len(dofs)} degrees of freedom: name the "
                    f"one it acts on, {' or '.join(f'{self.name}.on({v!r})' for v in velocities)}")
        if self.acts_on is not None and self.acts_on not in velocities:
            return (f"{self.name} acts on {self.acts_on!r}, which is no velocity of {physics.display_name}'s degrees "
                    f"of freedom {velocities}")
        return None

    def force(self, physics: nn.Module, x: torch.Tensor, v: torch.Tensor, u: torch.Tensor, z: torch.Tensor | None = None
              ) -> torch.Tensor | None:
        return None

    def rate(self, physics: nn.Module, x: torch.Tensor, u: torch.Tensor, z: torch.Tensor | None = None
             ) -> torch.Tensor | None:
        return None

    def state_rate(self, physics: nn.Module, x: torch.Tensor, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """$\\dot z$ (batch, k) of the effect's own states z (batch, k), from the physics' states x (batch, n_state)
        and the input u (batch, n_input). Effects with :attr:`own_states` must define it."""
        raise NotImplementedError(f"{self.name} declares own_states and must implement state_rate(physics, x, z, u)")

    def starts(self, records: list) -> list[dict[str, float]]:
        """Settings of the effect's other parameters (``{name: value}``) from which the ranking probes and refits
        it, derived from the measured ``records`` (the scale of y, of its rate): the ranking screens each by one
        probe and scores and refits the most promising. The default, ``[{}]``: the parameters as constructed."""
        return [{}]

    def bounds(self, records: list) -> dict[str, tuple[float, float]]:
        """Bounds ``{name: (lower, upper)}`` in physical units on the effect's parameters while the ranking refits it
        on ``records``, where a value beyond them means a state faster than the sampling resolves (a stiff model
        that costs every simulation dearly and that the records cannot tell from its limit). The default, ``{}``:
        none."""
        return {}

    def probe(self, records: list) -> float | None:
        """The strength at which the ranking probes the effect's first-order direction on ``records``, where its
        default (1e-4) does not suit; ``None`` (the default): the ranking's."""
        return None

    def input_map(self, u: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
        return u

    def output_map(self, y: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
        return y

    @staticmethod
    def on_state(physics: nn.Module, x: torch.Tensor, terms: dict[str, torch.Tensor]) -> torch.Tensor:
        """A ``rate`` (batch, n_state) that adds ``terms[name]`` (batch,) to the equation of each named state."""
        return state_vector([terms.get(name, torch.zeros_like(x[..., 0])) for name in physics.state_names])
