r"""The unconstrained baseline: multilayer perceptrons, a universal approximator in two placements.

* :class:`MLPResidual` (output-additive): $r_t = \mathrm{MLP}(u_{t-L+1..t}/s_u,\ \hat y_{t-L+1..t}/s_y)$,
  a NARX-style map of a window of $L$ past inputs and physics outputs (zeros before $t_0$: rest).
* :class:`MLPForce` inside :class:`ForceAugmented` (state-augmenting, a universal differential
  equation): $\ddot x = a_{\text{physics}}(t, x, \dot x, u) + \mathrm{MLP}(x/s_x, \dot x/s_v, u/s_u)$;
  on any physics, :class:`MLPRate` inside :class:`RateAugmented`: $\dot x = f(t, x, u) + E\,\mathrm{MLP}(x/s_x, u/s_u)$,
  a learned rate on chosen state equations (discovery's neural stage).

Neither has any structural relation to the physics, which is the point of the contrast: nothing
stops them from reproducing (and so replacing) the physics' own response.
"""

from __future__ import annotations

import torch
from torch import nn

from torchpaml._errors import ConfigurationError
from torchpaml._physics.base import AbstractPhysics, SecondOrderPhysics, state_vector
from torchpaml._residual.base import AbstractResidual

__all__ = ["MLPResidual", "MLPForce", "ForceAugmented", "MLPRate", "RateAugmented", "TanhNetwork", "mlp"]


class TanhNetwork(nn.Sequential):
    r"""``nn.Linear`` layers and ``nn.Tanh`` activations in sequence, (..., in) -> (..., out), each activation
    evaluated as a sigmoid whose factors are folded into the linear layers around it:

    $$ \tanh(W h + b) = 2\sigma(2 W h + 2 b) - 1, \qquad W'(2 s - 1) + b' = 2 W' s + (b' - W' \mathbf{1}). $$

    The same function as ``nn.Sequential`` of the same layers (within a few 1e-16 relative, float64; its modules and
    ``state_dict`` are the same), at one elementwise operation per activation: on CPU, torch's float64 ``tanh``
    takes about five times its ``sigmoid`` (3.3e6 elements on one thread: 20 ms against 4 ms), and a network
    simulated along a record spends most of its time in its activations. A slice (``net[1:]``) is one too.
    """

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        layers, halved, i = list(self), False, 0  # halved: h holds s, the true activation being 2s - 1
        while i < len(layers):
            layer = layers[i]
            if isinstance(layer, nn.Tanh):  # one that no linear layer precedes here
                h, halved, i = torch.sigmoid(h + h), True, i + 1
                continue
            if not isinstance(layer, nn.Linear):
                raise TypeError(f"TanhNetwork holds nn.Linear and nn.Tanh layers; got {type(layer).__name__}")
            weight = layer.weight
            bias = layer.bias if layer.bias is not None else weight.new_zeros(weight.shape[0])
            if halved:
                weight, bias = weight + weight, bias - weight.sum(dim=1)
            activated = i + 1 < len(layers) and isinstance(layers[i + 1], nn.Tanh)
            if activated:
                weight, bias = weight + weight, bias + bias
            h = nn.functional.linear(h, weight, bias)
            h, halved, i = (torch.sigmoid(h), True, i + 2) if activated else (h, False, i + 1)
        return h * 2 - 1 if halved else h


def mlp(inputs: int, hidden: int, depth: int, outputs: int = 1) -> TanhNetwork:
    """``depth`` hidden tanh layers of width ``hidden``, float64; the last layer starts at zero output."""
    layers, width = [], inputs
    for _ in range(depth):
        layers += [nn.Linear(width, hidden, dtype=torch.float64), nn.Tanh()]
        width = hidden
    last = nn.Linear(width, outputs, dtype=torch.float64)
    nn.init.zeros_(last.weight)
    nn.init.zeros_(last.bias)
    return TanhNetwork(*layers, last)


class MLPResidual(AbstractResidual):
    r"""Output-additive MLP on a window of past inputs and physics outputs.

    Args:
        window: $L$, the number of past samples of u and of $\hat y$ it sees.
        hidden: width of each hidden tanh layer.
        depth: number of hidden tanh layers.
        u_scale: $s_u$, divides the input u so that it is of order one.
        y_scale: $s_y$, divides the physics output $\hat y$ so that it is of order one.

    Shape: u, y_physics (batch, time, 1) -> r (batch, time, 1). Starts as the zero model.

    The first layer, a ``Linear`` on the flattened window $(u_{t-L+1..t}, \hat y_{t-L+1..t})$, is applied to
    every window at once as a causal ``conv1d`` with the same weights: no (time, 2L) copy of the
    windows is made, and its gradient in $\hat y$ (joint training) is a transposed convolution.
    """

    def __init__(self, window: int = 16, hidden: int = 32, depth: int = 2, *, u_scale: float = 1.0, y_scale: float = 1.0):
        super().__init__()
        self.window, self.u_scale, self.y_scale = int(window), float(u_scale), float(y_scale)
        self.net = mlp(2 * self.window, hidden, depth)

    def forward(self, t, u, y_physics=None):
        if y_physics is None:
            raise ConfigurationError("MLPResidual needs the physics output: call residual(t, u, y_physics)")
        signals = torch.cat([u / self.u_scale, y_physics / self.y_scale], dim=-1).transpose(1, 2)  # (B, 2, T)
        first = self.net[0]  # weight (hidden, 2L): channel c at lag L - 1 - j is column c * L + j
        padded = nn.functional.pad(signals, (self.window - 1, 0))  # rest before t0
        hidden = nn.functional.conv1d(padded, first.weight.view(-1, 2, self.window), first.bias)  # (B, hidden, T)
        return self.net[1:](hidden.transpose(1, 2))


class MLPForce(nn.Module):
    r"""A learned force $\mathrm{MLP}(x/s_x, v/s_v, u/s_u)$; x, v, u (batch,) -> (batch,). Starts at zero.

    Attributes:
        alpha: ``None``: a learned force has no Chebyshev domain (:class:`~torchpaml.AbstractResidual`'s).
    """

    alpha: float | None = None

    def __init__(self, hidden: int = 32, depth: int = 2, *, x_scale: float = 1.0, v_scale: float = 1.0, u_scale: float = 1.0):
        super().__init__()
        self.scales = (float(x_scale), float(v_scale), float(u_scale))
        self.net = mlp(3, hidden, depth)

    def forward(self, x, v, u):
        sx, sv, su = self.scales
        return self.net(torch.stack([x / sx, v / sv, u / su], dim=-1))[..., 0]


class ForceAugmented(SecondOrderPhysics):
    r"""Universal differential equation: ``physics`` with an extra force, $\ddot x = a(t, x, v, u) + F(x, v, u)$.

    The output map is the physics' own. Simulated by an ODE solver (it is nonlinear).
    """

    def __init__(self, physics: SecondOrderPhysics, force: MLPForce):
        super().__init__()
        base = physics.without_effects()  # physics + effects keeps its base's acceleration
        if not isinstance(base, SecondOrderPhysics):
            raise ConfigurationError(f"ForceAugmented needs second-order (mechanical) physics, got {type(physics).__name__}")
        self.physics, self.force = physics, force

    def acceleration(self, t, x, v, u):
        return self.physics.acceleration(t, x, v, u) + self.force(x, v, u)

    def output(self, x, u):
        return self.physics.output(x, u)

    def linear_base(self):
        return self.physics.linear_base()


class MLPRate(nn.Module):
    r"""A learned rate $\mathrm{MLP}(z/s)$ of the variables $z = (x, u)$, (batch, n_state + n_input) -> (batch, outputs).

    ``scales`` $s$ (one per variable) make the inputs of order one. Starts at zero.
    """

    def __init__(self, scales: list[float], outputs: int, hidden: int = 32, depth: int = 2):
        super().__init__()
        self.register_buffer("scales", torch.tensor(scales, dtype=torch.float64))
        self.net = mlp(len(scales), hidden, depth, outputs)

    def forward(self, z):
        return self.net(z / self.scales)


class RateAugmented(AbstractPhysics):
    r"""``physics`` with a learned rate on the state equations ``equations`` (indices):
    $\dot x = f(t, x, u) + E\,\mathrm{MLP}(x, u)$, $E$ the columns of those states. Output map: the physics'.
    """

    def __init__(self, physics: AbstractPhysics, rate: MLPRate, equations: list[int]):
        super().__init__()
        self.physics, self.rate, self.equations = physics, rate, list(equations)
        self.state_names, self.input_dim, self.output_dim = physics.state_names, physics.input_dim, physics.output_dim

    def derivative(self, t, x, u):
        dx = self.physics.derivative(t, x, u)
        extra = self.rate(torch.cat([x, u], dim=-1))
        columns = [dx[..., i] for i in range(dx.shape[-1])]
        for j, i in enumerate(self.equations):
            columns[i] = columns[i] + extra[..., j]
        return state_vector(columns)

    def learned(self, x, u):
        """The learned rate on every state equation, x (..., n_state), u (..., n_input) -> (..., n_state)."""
        extra = self.rate(torch.cat([x, u], dim=-1))
        full = torch.zeros_like(x)
        full[..., self.equations] = extra
        return full

    def output(self, x, u):
        return self.physics.output(x, u)

    def initial_state(self, batch):
        return self.physics.initial_state(batch)

    def linear_base(self):
        return self.physics.linear_base()
