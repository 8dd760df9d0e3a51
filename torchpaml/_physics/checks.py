"""A user's physics checked at the door: each method evaluated once on a record's first samples, before any fit.

:func:`check_physics` calls ``acceleration`` (second-order physics), ``derivative`` and ``output`` at
the starting parameters, from the model's initial state, on the first :data:`SAMPLES` samples, and
raises :class:`~torchpaml.PhysicsError` in one line naming the class and the method:

* an exception inside the method: its type and message (the original traceback is chained, and the
  CLI prints it under ``--verbose``);
* a result of the wrong shape: the shape returned and the shape expected;
* NaN or infinity: the parameters it was evaluated at, instead of a simulation that "blew up" later.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from torchpaml._errors import ConfigurationError, DataError, PhysicsError
from torchpaml._physics.base import AbstractPhysics, SecondOrderPhysics

__all__ = ["TIME_SCALE_LIMIT", "check_channels", "check_degrees_of_freedom", "check_physics", "check_time_scale"]

#: Samples of the record the methods are evaluated on.
SAMPLES = 4
#: $\omega\,\Delta t$ beyond which a record's time step cannot be in seconds for a physics
#: (:func:`check_time_scale`): five periods of its fastest oscillation between two samples.
TIME_SCALE_LIMIT = 10 * math.pi


def _evaluate(name: str, method: str, call: Callable[[], torch.Tensor], expected: tuple[int, ...], meaning: str,
              parameters: dict[str, float]) -> None:
    try:
        with torch.no_grad():
            value = call()
    except Exception as error:  # the user's code: any exception is reported as theirs
        raise PhysicsError(f"{name}.{method} raised {type(error).__name__}: {error} (at the starting parameters, on "
                           "the first samples); fix the method (--verbose prints the traceback)") from error
    shape = tuple(value.shape) if torch.is_tensor(value) else type(value).__name__
    if shape != expected:
        raise PhysicsError(f"{name}.{method} returned shape {shape}, expected {expected} ({meaning}); return one value "
                           "per row of the batch")
    if not bool(torch.isfinite(value).all()):
        raise PhysicsError(f"{name}.{method} returned NaN or infinity at the starting parameters "
                           f"{ {k: float(f'{v:.4g}') for k, v in parameters.items()} } on the first samples; check "
                           "the formula (a division by a state that starts at 0, a log or sqrt of a negative value)")


def check_channels(physics: AbstractPhysics, record, missing: bool = False) -> None:
    """:class:`~torchpaml.DataError` in one line where a :class:`~torchpaml.Record`'s input and output channels are
    not the physics' ``input_dim`` and ``output_dim``, or where both name them and the names differ, or where its
    outputs have missing samples (NaN, metadata ``"missing_outputs"``) and ``missing`` does not allow them (a fit
    does not; a tracker predicts through them); a :class:`~torchpaml.ConfigurationError` where the physics names a
    number of channels other than its own."""
    if record.metadata.get("missing_outputs") and not missing:
        raise DataError(f"record {record.name!r} has {record.metadata['missing_outputs']} sample(s) whose output is "
                        "missing (NaN): a fit needs every output measured; drop or interpolate those samples (a "
                        "tracker predicts through them: torchpaml track)")
    counts = {"input": record.u.shape[1], "output": record.y.shape[1]}
    for what, given in counts.items():
        declared, names = getattr(physics, f"{what}_dim"), tuple(getattr(physics, f"{what}_names"))
        if given != declared:
            raise DataError(f"record {record.name!r} has {given} {what} channel(s), but {physics.display_name} has "
                            f"{declared} ({what}_dim); give records with {declared} {what} column(s) (header "
                            f"t,u1,…,y1,…), or a physics whose {what}_dim is {given}")
        if names and len(names) != declared:
            raise ConfigurationError(f"{physics.display_name} names {len(names)} {what}(s) {list(names)} but has "
                                     f"{declared} ({what}_dim); name one per channel")
        named = record.metadata.get(f"{what}s")
        if names and named is not None and tuple(named) != names:
            raise DataError(f"record {record.name!r} names its {what}s {list(named)}, but {physics.display_name} "
                            f"names them {list(names)}; rename the record's columns (its metadata's \"{what}s\") "
                            f"or the physics' {what}_names")


def check_degrees_of_freedom(physics: AbstractPhysics) -> None:
    """:class:`~torchpaml.ConfigurationError` in one line where ``degrees_of_freedom`` names a state that the physics
    does not have (its ``state_names``)."""
    base = physics.without_effects()
    for pair in base.degrees_of_freedom:
        unknown = [name for name in pair if name not in base.state_names]
        if unknown:
            raise ConfigurationError(f"{base.display_name}.degrees_of_freedom names state(s) {unknown} in "
                                     f"{tuple(pair)}, but its states are {list(base.state_names)}; name a (position, "
                                     "velocity) pair of state_names")


def check_time_scale(physics: AbstractPhysics, record) -> None:
    r""":class:`~torchpaml.DataError` in one line where ``record``'s time step cannot be in seconds for ``physics``: its
    linearisation at the initial state and the first input, $A = \partial f/\partial x$, oscillates at
    $\omega = \max|\mathrm{Im}\,\lambda(A)|$ rad/s, and $\omega\,\Delta t$ above :data:`TIME_SCALE_LIMIT` means
    five periods or more between two samples: no sampling of that physics, but the sign of a time written in
    milliseconds. Physics whose methods autograd cannot differentiate is not checked here (its fit says more)."""
    x0, dt = physics.initial_state(1).to(record.u), float(record.t[1] - record.t[0]) if len(record.t) > 1 else 0.0
    try:
        A = torch.autograd.functional.jacobian(lambda x: physics.derivative(record.t[:1], x, record.u[:1]), x0)
        omega = float(torch.linalg.eigvals(A.reshape(x0.shape[1], x0.shape[1])).imag.abs().max())
    except (RuntimeError, TypeError, ValueError, NotImplementedError):  # not differentiable: its fit says more
        return
    if omega * dt > TIME_SCALE_LIMIT:
        periods = omega * dt / (2 * math.pi)
        raise DataError(f"record {record.name!r} is sampled every {dt:.6g} s, but {physics.display_name} at its "
                        f"starting parameters oscillates at {omega:.3g} rad/s, {periods:.3g} periods per sample: "
                        "give t in seconds (a time in milliseconds is divided by 1000), or start the physics' "
                        "parameters nearer the device's")


def check_physics(physics: AbstractPhysics, t: torch.Tensor, u: torch.Tensor) -> None:
    """Evaluate ``physics``' methods once (module docstring) on t (time,), u (time, n_input); ``PhysicsError`` if
    one fails. Its ``degrees_of_freedom`` are checked first (:func:`check_degrees_of_freedom`)."""
    check_degrees_of_freedom(physics)
    k = min(SAMPLES, len(t))
    name, parameters = physics.display_name, physics.physical_parameters()
    x, u, t = physics.initial_state(k).to(u), u[:k], t[:k]
    n = physics.state_dim
    base = physics.without_effects()
    if isinstance(base, SecondOrderPhysics) and base is physics:
        _evaluate(name, "acceleration", lambda: physics.acceleration(t, x[:, 0], x[:, 1], u[:, 0]), (k,),
                  "(batch,) from x, v, u of shape (batch,)", parameters)
    _evaluate(name, "derivative", lambda: physics.derivative(t, x, u), (k, n),
              "(batch, n_state) from x (batch, n_state)", parameters)
    _evaluate(name, "output", lambda: physics.output(x, u), (k, physics.output_dim),
              "(batch, n_output) from x (batch, n_state)", parameters)
