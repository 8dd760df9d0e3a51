r"""Base classes for physics models: subclass one of them to write your own ODE physics.

Conventions (written once for the whole package): argument order ``(t, x, u)``; a state ``x`` has
shape (batch, n_state), an input sample ``u`` (batch, n_input), signals are (batch, time, channel);
float64; time in seconds.

A physics model is the operator $\mathcal H^\theta: u \mapsto y$ given by

$$ \dot x = f(t, x, u; \theta), \qquad y = h(x, u; \theta), \qquad x(t_0) = x_0 . $$

Writing your own::

    class Tank(AbstractPhysics):
        state_names = ("level",)

        def __init__(self, area=1.0, outflow=0.5, *, learn=("outflow",)):
            super().__init__()
            register_parameters(self, [
                PhysicalParameter("area", area, "m^2", Positive()),
                PhysicalParameter("outflow", outflow, "m^2.5/s", Positive()),
            ], learn)

        def derivative(self, t, x, u):
            return (u - self.outflow * x.clamp(min=0).sqrt()) / self.area

        def output(self, x, u):
            return x

Linear physics may also return its matrices from :meth:`AbstractPhysics.state_space`; the simulator
then uses the exact discretisation instead of an ODE solver.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn.utils import parametrize

from torchpaml._arguments import Rebuildable
from torchpaml._errors import ConfigurationError
from torchpaml._simulate.dynamics import complete_state
from torchpaml._simulate.simulator import simulate
from torchpaml._parameters import (Interval, constrain, copied_with_own_parametrizations, declared,
                                  describe_parameters, format_table, with_uncertainty)

__all__ = ["AbstractPhysics", "SecondOrderPhysics", "complete_state", "state_vector"]


def state_vector(columns: list[torch.Tensor]) -> torch.Tensor:
    """The state derivative (batch, n_state) from one column (batch,) per state equation.

    Stored state-major (each state's column contiguous), like the states the RK4 engine passes in, so
    that the solver's arithmetic and the next ``x[..., i]`` stay on contiguous memory. Use it in place
    of ``torch.stack(columns, dim=-1)``, which interleaves the columns and costs several times more.
    """
    return torch.stack(columns).movedim(0, -1)


class AbstractPhysics(Rebuildable, nn.Module):
    """Abstract ODE physics $\\dot x = f(t, x, u)$, $y = h(x, u)$. Subclasses define the two maps.

    A physics holds its parameters and its equations, not an integrator: calling it, ``physics(t, u)``, simulates it
    with the default solver (``Auto()``) unless given one, and a fit leaves that meaning alone (its result carries
    the solver it resolved, ``PhysicsEstimate.solver``; pass it as ``solver=`` to simulate as the fit did).
    """

    state_names: tuple[str, ...] = ()
    input_dim: int = 1
    output_dim: int = 1
    #: The channels' names, where the physics names them (``("force",)``, ``("x1", "x2")``): a record that declares
    #: other names (its metadata's ``"inputs"`` / ``"outputs"``) is refused, and the diagnosis reports each output
    #: by them where the records do not name it. Default: unnamed.
    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()
    #: The mechanical degrees of freedom, as (position, velocity) pairs of state names, where a force effect may
    #: act (``CoulombFriction().on("v2")``): ``(("x1", "v1"), ("x2", "v2"))`` for a two-mass chain. Default none:
    #: only effects that name their states (rates) and maps apply.
    degrees_of_freedom: tuple[tuple[str, str], ...] = ()

    def __deepcopy__(self, memo: dict) -> AbstractPhysics:
        """A copy that reads its own parameter values (:func:`~torchpaml._parameters.copied_with_own_parametrizations`)."""
        return copied_with_own_parametrizations(self, memo)

    @property
    def state_dim(self) -> int:
        return len(self.state_names)

    def derivative(self, t: torch.Tensor, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """$f(t, x, u)$: t scalar tensor, x (batch, n_state), u (batch, n_input) -> (batch, n_state)."""
        raise NotImplementedError(f"{self.display_name} must implement derivative(t, x, u)")

    def output(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """$h(x, u)$: x (batch, ..., n_state), u (batch, ..., n_input) -> (batch, ..., n_output)."""
        raise NotImplementedError(f"{self.display_name} must implement output(x, u)")

    def state_space(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor] | None:
        """$(A, B, C, D)$ for linear physics, ``None`` (the default) for nonlinear physics."""
        return None

    def equation(self) -> str:
        """The model in words: the class's name (a composed model adds each effect's term)."""
        return self.display_name

    def without_effects(self) -> AbstractPhysics:
        """The physics under the added effects: itself (a composed model's ``base``)."""
        return self

    def effect_names(self) -> tuple[str, ...]:
        """The names of the effects added to the physics: none (a composed model's)."""
        return ()

    def linear_base(self) -> AbstractPhysics | None:
        """Linear physics on the same states whose trajectory lies near this model's, or ``None``: the model itself
        when linear; a composed model's base; the physics under a learned force. The RK4 engine starts Newton
        from its exact trajectory."""
        return self if self.state_space() is not None else None

    def initial_state(self, batch: int) -> torch.Tensor:
        """Rest, shape (batch, n_state)."""
        return torch.zeros(batch, self.state_dim, dtype=torch.float64)

    def forward(self, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor | None = None, **options) -> torch.Tensor:
        """``simulate(self, t, u, x0, **options)``: t (time,), u (batch, time, n_input) -> y (batch, time, n_output),
        by ``Auto()`` unless ``solver=`` is given (:func:`~torchpaml.simulate`)."""
        return simulate(self, t, u, x0, **options)

    # -- parameters --------------------------------------------------------------------------
    def _rows(self) -> list[dict]:
        """:func:`~torchpaml._parameters.describe_parameters` rows under the names users read and assign."""
        return describe_parameters(self)

    def physical_parameters(self) -> dict[str, float]:
        """Current values in physical units, ``{name: value}``."""
        return {r["name"]: r["value"] for r in self._rows()}

    def learnable_names(self) -> list[str]:
        return [r["name"] for r in self._rows() if r["learnable"]]

    def set_learnable(self, *names: str, learn: bool = True) -> AbstractPhysics:
        """Make the named parameters learnable (or fixed with ``learn=False``); returns ``self``."""
        known = set(self.physical_parameters())
        for name in names:
            if name not in known:
                raise ConfigurationError(f"{self.display_name} has no physical parameter {name!r}; known: {sorted(known)}")
            owner, leaf = self._owner(name)
            getattr(owner.parametrizations, leaf).original.requires_grad_(learn)
        return self

    def assign(self, **values: float) -> AbstractPhysics:
        """Set parameters in physical units, checking their constraints; returns ``self``."""
        for name, value in values.items():
            owner, leaf = self._owner(name)
            if leaf not in declared(owner):
                raise ConfigurationError(f"{self.display_name} has no physical parameter {name!r}")
            owner._physical[leaf].constraint.check(name, float(value))
            with torch.no_grad():
                setattr(owner, leaf, torch.tensor(float(value), dtype=torch.float64))
        return self

    def bound(self, name: str, lower: float, upper: float) -> AbstractPhysics:
        r"""Constrain parameter ``name`` to the open interval (lower, upper) from now on; returns ``self``.

        The parameter keeps its value and its fixed/learned status; its parametrisation becomes
        :class:`~torchpaml.Interval` (gradient-based fits then cannot leave the interval).
        """
        owner, leaf = self._owner(name)
        if leaf not in declared(owner):
            raise ConfigurationError(f"{self.display_name} has no physical parameter {name!r}")
        value = float(getattr(owner, leaf).detach())
        interval = Interval(lower, upper)
        try:
            interval.check(name, value)
        except ValueError as err:
            raise ConfigurationError(f"{err}; start {name} inside the bounds, e.g. assign({name}=...)") from None
        constrain(owner, leaf, interval)
        return self

    def _owner(self, name: str) -> tuple[nn.Module, str]:
        path, _, leaf = name.rpartition(".")
        return (self.get_submodule(path) if path else self), leaf

    def describe(self, uncertainty=None) -> str:
        """A readable table of the physical parameters (value, unit, constraint, fixed/learned), with the standard
        errors and 95 % intervals of ``uncertainty`` (a fit's, ``PhysicsEstimate.uncertainty``) where given."""
        return f"{self.display_name}\n{self._table(uncertainty)}"

    def _table(self, uncertainty) -> str:
        rows = self._rows()
        return format_table(rows if uncertainty is None else with_uncertainty(rows, uncertainty.std,
                                                                             uncertainty.interval))

    @property
    def display_name(self) -> str:
        """The class name (without the ``Parametrized`` prefix that torch's parametrisation adds)."""
        cls = type(self)
        return cls.__bases__[0].__name__ if parametrize.is_parametrized(self) else cls.__name__


class SecondOrderPhysics(AbstractPhysics):
    r"""Mechanical physics with state (position $x$, velocity $v$): $\dot x = v$, $\dot v = a(t, x, v, u)$, $y = x$."""

    state_names = ("position", "velocity")
    degrees_of_freedom = (("position", "velocity"),)

    def acceleration(self, t: torch.Tensor, x: torch.Tensor, v: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """$a(t, x, v, u)$ with x, v, u of shape (batch,) -> (batch,)."""
        raise NotImplementedError(f"{self.display_name} must implement acceleration(t, x, v, u)")

    def derivative(self, t, x, u):
        pos, vel = x[..., 0], x[..., 1]
        return state_vector([vel, self.acceleration(t, pos, vel, u[..., 0])])

    def output(self, x, u):
        return x[..., :1]
