"""A physics traced by ``torch.export`` into one program of ATen operations: its rates $f(t, x, u)$ and its output
$h(x, u)$ on one row. Every closed form interprets this program (:func:`~torchpaml._symbolic.aten.interpret`): the
exports' (parameters as numbers) and the compiled simulation's (parameters as symbols read at run time)."""

from __future__ import annotations

import torch
from torch import nn

from torchpaml._errors import ConfigurationError

__all__ = ["traced"]


class _Maps(nn.Module):
    def __init__(self, physics: nn.Module):
        super().__init__()
        self.physics = physics

    def forward(self, t: torch.Tensor, x: torch.Tensor, u: torch.Tensor):
        return self.physics.derivative(t, x, u), self.physics.output(x, u)


def traced(physics: nn.Module) -> torch.export.ExportedProgram:
    """``physics.derivative`` and ``physics.output`` on one float64 row (t (1,), x (1, n_state), u (1, n_input)), as
    a ``torch.export`` program whose parameter and buffer targets are prefixed ``physics.``; a physics that
    ``torch.export`` cannot trace is refused in one line (:class:`~torchpaml.ConfigurationError`)."""
    example = (torch.zeros(1, dtype=torch.float64), torch.zeros(1, physics.state_dim, dtype=torch.float64),
               torch.zeros(1, physics.input_dim, dtype=torch.float64))
    modes = {module: module.training for module in physics.modules()}
    try:
        return torch.export.export(_Maps(physics).eval(), example)
    except Exception as error:  # noqa: BLE001 - torch.export reports what it cannot trace in many types
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise ConfigurationError(f"cannot export {physics.display_name}: torch.export cannot trace its derivative or "
                                 f"output ({reason[:200]})") from None
    finally:
        for module, training in modes.items():  # traced in eval mode; the caller's modules keep theirs
            module.training = training
