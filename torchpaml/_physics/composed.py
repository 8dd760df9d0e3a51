r"""``physics + effect``: any physics with extra effects, as one physics model.

$$ \dot x = f_{\text{base}}(t, x, \tilde u) + \sum_e R_e(x, u) + e_v \sum_e F_e(x, v, u), \qquad
   \tilde u = m_{\text{in}}(u), \qquad y = m_{\text{out}}(h_{\text{base}}(x, \tilde u)), $$

with the rates $R_e$ on named state equations, the forces $F_e$ on the velocity equation $e_v$ of their degree of
freedom (:attr:`~torchpaml.AbstractPhysics.degrees_of_freedom`; on second-order physics
$\ddot x = a_{\text{base}} + \sum_e F_e$), the input maps $m_{\text{in}}$ and output maps $m_{\text{out}}$ of the effects applied in the
order they were added. An effect with its own states $z_e$ (:attr:`~torchpaml.AbstractEffect.own_states`:
hysteresis, dynamic friction, a lagged input or sensor) appends them to the state vector, $\dot z_e = g_e(x, z_e, u)$,
after the base's states, named ``effect.state``; its force, rate and maps then read $z_e$ too. A state of the
base's states alone, wherever one is passed, is completed with the effects' declared initial values
(:func:`~torchpaml.complete_state`). Parameters keep their names: the base's (``zeta``, ``omega0``, ...) and each
effect's under its name (``cubic_stiffness.k3``). Composition flattens:
``(Oscillator() + CubicStiffness()) + QuadraticDamping()`` is one ``ComposedModel`` with two effects,
and adding an effect whose name is already present raises ``ValueError``.
"""

from __future__ import annotations

import torch
from torch import nn

from torchpaml._errors import ConfigurationError
from torchpaml._parameters import describe_parameters
from torchpaml._physics.base import AbstractPhysics, SecondOrderPhysics, state_vector

__all__ = ["ComposedModel", "compose"]


def compose(physics: AbstractPhysics, effect) -> ComposedModel:
    """``physics + effect`` (see the module docstring), called by the effect (:class:`~torchpaml.AbstractEffect`)."""
    if not isinstance(physics, AbstractPhysics):
        raise ConfigurationError(f"an effect is added to physics (physics + effect), got {type(physics).__name__} + "
                                 f"{type(effect).__name__}")
    if isinstance(physics, ComposedModel):
        return ComposedModel(physics.base, [*physics.effects.values(), effect])
    return ComposedModel(physics, [effect])


class ComposedModel(AbstractPhysics):
    """``base`` physics with ``effects`` (module docstring). Nonlinear: simulated by the RK4 engine.

    Raises ``TypeError`` naming the reason for an effect that does not apply to ``base``
    (:meth:`~torchpaml.AbstractEffect.applies_to`).
    """

    def __init__(self, base: AbstractPhysics, effects: list):
        super().__init__()
        for effect in effects:
            reason = effect.applies_to(base)
            if reason is not None:
                raise ConfigurationError(f"cannot add {effect.name or type(effect).__name__}: {reason}; write the effect into "
                                "your own physics instead, or choose effects that apply")
        names = [e.name for e in effects]
        clashes = sorted({n for n in names if names.count(n) > 1})
        if clashes:
            raise ConfigurationError(f"effect(s) {clashes} added twice; each effect may appear once in a model")
        if not all(names):
            raise ConfigurationError("every effect needs a non-empty class attribute `name`")
        self.base = base
        self.effects = nn.ModuleDict({e.name: e for e in effects})
        self.state_names = (*base.state_names,
                            *(f"{e.name}.{s.name}" for e in effects for s in e.own_states))
        self.input_dim, self.output_dim = base.input_dim, base.output_dim
        self.input_names, self.output_names = base.input_names, base.output_names

    def _own(self, x: torch.Tensor) -> tuple[torch.Tensor, dict[str, tuple[torch.Tensor, ...]]]:
        """The base's states (..., n_base) and, per effect, the extra hook argument: ``(z,)`` (..., k) for an
        effect with own states, ``()`` for one without."""
        n, own = self.base.state_dim, {}
        for name, effect in self.effects.items():
            k = len(effect.own_states)
            own[name] = (x[..., n:n + k],) if k else ()
            n += k
        return x[..., :self.base.state_dim], own

    def _mapped(self, u, own):
        for name, effect in self.effects.items():
            u = effect.input_map(u, *own[name])
        return u

    def derivative(self, t, x, u):
        x, own = self._own(x)
        mapped = self._mapped(u, own)
        if isinstance(self.base, SecondOrderPhysics):  # its one degree of freedom: forces add to the acceleration
            pos, vel = x[..., 0], x[..., 1]
            acceleration = self.base.acceleration(t, pos, vel, mapped[..., 0])
            for name, effect in self.effects.items():
                force = effect.force(self.base, pos, vel, u[..., 0], *own[name])
                if force is not None:
                    acceleration = acceleration + force
            dx = state_vector([vel, acceleration])
        else:
            dx = self.base.derivative(t, x, mapped)
            forces = self._forces(x, u, own)
            if forces is not None:
                dx = dx + forces
        for name, effect in self.effects.items():
            extra = effect.rate(self.base, x, u, *own[name])
            if extra is not None:
                dx = dx + extra
        rates = [effect.state_rate(self.base, self._seen(effect, x), own[name][0], u)
                 for name, effect in self.effects.items() if effect.own_states]
        if not rates:
            return dx
        return state_vector([*dx.unbind(-1), *(column for rate in rates for column in rate.unbind(-1))])

    def _forces(self, x: torch.Tensor, u: torch.Tensor, own: dict) -> torch.Tensor | None:
        """The forces on the degrees of freedom of a base other than a :class:`SecondOrderPhysics`, (batch, n_base):
        each on its velocity's equation (:meth:`~torchpaml.AbstractEffect.degree_of_freedom`); ``None`` without one."""
        total = None
        for name, effect in self.effects.items():
            if not effect.is_force:
                continue
            i, j = effect.degree_of_freedom(self.base)
            force = effect.force(self.base, x[..., i], x[..., j], u[..., 0], *own[name])
            velocity = self.base.state_names[j]
            term = effect.on_state(self.base, x, {velocity: force})
            total = term if total is None else total + term
        return total

    def _seen(self, effect, x: torch.Tensor) -> torch.Tensor:
        """The base's states as an effect with memory reads them: a force's degree of freedom as the columns
        (position, velocity), else every state."""
        if not effect.is_force or isinstance(self.base, SecondOrderPhysics):
            return x
        i, j = effect.degree_of_freedom(self.base)
        return torch.stack([x[..., i], x[..., j]], dim=-1)

    def acceleration(self, t, x, v, u):
        """$\\ddot x$ of a second-order base with the effects, x, v, u of shape (batch,) -> (batch,); effects with own
        states have no acceleration of (x, v) alone."""
        if not isinstance(self.base, SecondOrderPhysics):
            raise ConfigurationError(f"acceleration is defined for second-order physics; {self.base.display_name} is not")
        if self.state_dim > 2:
            raise ConfigurationError(f"{self.display_name} carries effect states {list(self.state_names[2:])}: its acceleration "
                            "depends on them too; call derivative(t, x, u) with the whole state")
        return self.derivative(t, torch.stack([x, v], dim=-1), u[..., None])[..., 1]

    def output(self, x, u):
        x, own = self._own(x)
        y = self.base.output(x, self._mapped(u, own)).movedim(0, -1)  # batch last: parameters batched as (rows,)
        for name, effect in self.effects.items():
            seen = {"u": u.movedim(0, -1)} if effect.reads_input else {}
            if effect.reads_state:
                seen |= {"x": x.movedim(0, -1), "physics": self.base}
            y = effect.output_map(y, *(z.movedim(0, -1) for z in own[name]), **seen)
        return y.movedim(-1, 0)

    def initial_state(self, batch):
        initial = [s.initial for e in self.effects.values() for s in e.own_states]
        extra = torch.tensor(initial, dtype=torch.float64).expand(batch, len(initial))
        return torch.cat([self.base.initial_state(batch), extra], dim=-1)

    def linear_base(self):
        return self.base.linear_base()

    # -- names: the base's parameters unprefixed, the effects' under their names ---------------
    def _rows(self) -> list[dict]:
        rows = describe_parameters(self.base)
        for name, effect in self.effects.items():
            rows += describe_parameters(effect, prefix=f"{name}.")
        return rows

    def describe(self, uncertainty=None) -> str:
        """The equation, the parameter table (with ``uncertainty``, as :meth:`AbstractPhysics.describe`) and the
        effects' own states (name, unit, meaning, initial value)."""
        states = [f"{name}.{s.name} ({s.unit}): {s.meaning}, starts at {s.initial:g}"
                  for name, effect in self.effects.items() for s in effect.own_states]
        text = f"{self.display_name}: {self.equation()}\n{self._table(uncertainty)}"
        return text + "".join(f"\nstate {line}" for line in states)

    def _owner(self, name: str) -> tuple[nn.Module, str]:
        head, _, leaf = name.partition(".")
        if leaf and head in self.effects:
            return self.effects[head], leaf
        return self.base, name

    def without_effects(self) -> AbstractPhysics:
        return self.base

    def effect_names(self) -> tuple[str, ...]:
        return tuple(self.effects)

    def equation(self) -> str:
        """The model in words: the base's class and each effect's term."""
        return " ".join([type(self.base).__name__.removeprefix("Parametrized"),
                         *(e.equation for e in self.effects.values())])

    @property
    def display_name(self) -> str:
        return " + ".join([self.base.display_name, *self.effects])
