r"""A physics' rates $f(t, x, u)$ and output $h(x, u)$ as sympy expressions, by running it once.

:func:`symbolic_maps` calls ``physics.derivative`` and ``physics.output`` on one float64 row of zeros under a
``TorchDispatchMode``. Every ATen operation the two calls reach runs on its tensors as usual (so shapes, broadcasting
and the physics' own Python are real), and the mode applies the same operation (:data:`~torchpaml._symbolic.aten.OPS`)
to the tensors' symbolic twins: numpy object arrays of sympy expressions. The inputs' twins are the given symbols; a
parameter's or buffer's twin is what ``tensors`` gives for its name, else its value as numbers; any other tensor (a
constant the physics makes) is its value. The outputs' twins are the closed form.

A physics cannot be taken (:class:`~torchpaml.ConfigurationError`, one line) where it:

- uses an operation outside :data:`~torchpaml._symbolic.aten.OPS`, an in-place one among them (``x.add_``,
  ``out[:, 0] = ...``): write it out of place;
- reads a number out of a tensor (``.item()``, ``float(x)``, ``if x > 0:``): a branch on the state is written
  ``torch.where``;
- raises on the zeros row.

Autograd is off while it runs, and the modules run in eval mode (each keeps its own mode afterwards).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils._pytree import tree_map

from torchpaml._errors import ConfigurationError
from torchpaml._symbolic.aten import OPS, as_array

__all__ = ["symbolic_maps"]

#: Keyword arguments of ATen's factories and copies that say where a tensor lives, not what it holds.
_PLACEMENT = ("dtype", "layout", "device", "pin_memory", "memory_format", "non_blocking")


class _Symbolic(TorchDispatchMode):
    """Each ATen call run as usual and, by :data:`~torchpaml._symbolic.aten.OPS`, on the symbolic twins of its
    tensors (module docstring); :attr:`twins` maps ``id(tensor)`` to ``(tensor, twin)`` (the tensor is kept, so an
    id is never reused while the mode runs)."""

    def __init__(self, owner: str, known: list[tuple[torch.Tensor, np.ndarray]]):
        super().__init__()
        self.owner = owner
        self.twins = {id(tensor): (tensor, twin) for tensor, twin in known}

    def twin(self, value):
        """The symbolic twin of ``value``: a known tensor's, another tensor's numbers, anything else as it is."""
        if not isinstance(value, torch.Tensor):
            return value
        entry = self.twins.get(id(value))
        return entry[1] if entry is not None and entry[0] is value else as_array(value)

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        action = OPS.get(func)
        if action is None:
            reason = ("it reads a number out of a tensor (.item(), float(), an if on a tensor); branch with "
                      "torch.where" if func is torch.ops.aten._local_scalar_dense.default else
                      f"the exporter does not know the operation {func}; write the physics with the out-of-place "
                      "operations listed in torchpaml._symbolic.aten.OPS")
            raise ConfigurationError(f"cannot export {self.owner}: {reason}")
        result = func(*args, **kwargs)
        twin = action(*tree_map(self.twin, list(args)),
                      **{key: tree_map(self.twin, value) for key, value in kwargs.items() if key not in _PLACEMENT})
        pairs = zip(result, twin, strict=True) if isinstance(result, (tuple, list)) else [(result, twin)]
        for tensor, value in pairs:
            self.twins[id(tensor)] = (tensor, value)
        return result


def symbolic_maps(physics: nn.Module, values: dict[str, np.ndarray],
                  tensors: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``physics``' rates (1, n_state) and output (1, n_output) as object arrays of sympy expressions (module
    docstring).

    Args:
        physics: the physics (``derivative(t, x, u)``, ``output(x, u)``, ``state_dim``, ``input_dim``).
        values: the symbols ``{"t": (1,), "x": (1, n_state), "u": (1, n_input)}`` (object arrays).
        tensors: the twins of parameters and buffers by their ``named_parameters``/``named_buffers`` name (object
            arrays of their shapes); the others enter as their values.
    """
    t = torch.zeros(1, dtype=torch.float64)
    x = torch.zeros(1, physics.state_dim, dtype=torch.float64)
    u = torch.zeros(1, physics.input_dim, dtype=torch.float64)
    named = {**dict(physics.named_parameters()), **dict(physics.named_buffers())}
    known = [(t, values["t"]), (x, values["x"]), (u, values["u"])]
    known += [(tensor, (tensors or {}).get(name, as_array(tensor))) for name, tensor in named.items()]
    modes = {module: module.training for module in physics.modules()}
    physics.eval()
    try:
        with torch.no_grad(), _Symbolic(physics.display_name, known) as mode:
            rates, output = physics.derivative(t, x, u), physics.output(x, u)
        return mode.twin(rates), mode.twin(output)
    except ConfigurationError:
        raise
    except Exception as error:  # noqa: BLE001 - a user's physics can fail on the zeros row in any way
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise ConfigurationError(f"cannot export {physics.display_name}: its derivative or output fails on one row "
                                 f"of zeros ({reason[:200]})") from None
    finally:
        for module, training in modes.items():  # run in eval mode; the caller's modules keep theirs
            module.training = training
