"""The networks' folded sigmoid form against the plain ``nn.Sequential`` of the same layers (``torch.tanh``).

Tolerance: $2\\sigma(2x) - 1$ differs from $\\tanh x$ by a few 1e-16 absolute, and the folded bias
$b' - W'\\mathbf{1}$ by rounding of a sum of 32 terms, so the outputs agree to 1e-14 relative to their
largest magnitude, at weights of order one (pre-activations up to about ten).
"""

import pytest
import torch
from torch import nn

from torchpaml._residual.mlp import MLPResidual, TanhNetwork, mlp


def _network(inputs=3, hidden=32, depth=2, outputs=2, seed=0):
    torch.manual_seed(seed)
    net = mlp(inputs, hidden, depth, outputs)
    for layer in net:
        if isinstance(layer, nn.Linear):
            nn.init.normal_(layer.weight)
            nn.init.normal_(layer.bias)
    return net


def _close(a, b, rtol=1e-14):
    return float((a - b).abs().max()) <= rtol * float(b.abs().max())


@pytest.mark.parametrize("depth", [1, 2, 3])
def test_the_folded_network_is_the_tanh_network(depth):
    net = _network(depth=depth)
    plain = nn.Sequential(*net)
    z = torch.randn(500, 3, dtype=torch.float64)
    with torch.no_grad():
        assert _close(net(z), plain(z))


def test_layers_without_a_bias_fold_too():
    torch.manual_seed(1)
    layers = [nn.Linear(3, 8, bias=False, dtype=torch.float64), nn.Tanh(), nn.Linear(8, 2, bias=False, dtype=torch.float64)]
    z = torch.randn(50, 3, dtype=torch.float64)
    with torch.no_grad():
        assert _close(TanhNetwork(*layers)(z), nn.Sequential(*layers)(z))


def test_a_slice_that_starts_at_an_activation_is_the_plain_slice():
    """MLPResidual applies its first layer as a convolution and the rest as ``net[1:]``."""
    net = _network()
    tail = net[1:]
    assert isinstance(tail, TanhNetwork) and isinstance(tail[0], nn.Tanh)
    h = 3 * torch.randn(200, 32, dtype=torch.float64)
    with torch.no_grad():
        assert _close(tail(h), nn.Sequential(*tail)(h))


def test_its_parameters_and_state_dict_are_those_of_the_plain_sequential():
    """Checkpoints keep their keys: ``net.0.weight``, ``net.2.weight``, ``net.4.weight`` and the biases."""
    residual = MLPResidual(window=4, hidden=8, depth=2)
    assert sorted(residual.state_dict()) == sorted(
        f"net.{i}.{kind}" for i in (0, 2, 4) for kind in ("weight", "bias"))


def test_its_gradients_are_exact_in_every_mode():
    net = _network(inputs=2, hidden=4, outputs=1)
    z = torch.randn(6, 2, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda z: net(z), (z,), check_forward_ad=True)
    assert torch.autograd.gradgradcheck(lambda z: net(z), (z,))
    first = net[0].weight.detach().clone().requires_grad_(True)
    assert torch.autograd.gradcheck(
        lambda w: torch.func.functional_call(net, {"0.weight": w}, (z.detach(),)), (first,), check_forward_ad=True)


def test_its_gradient_in_the_weights_is_the_plain_networks():
    net = _network()
    plain = nn.Sequential(*net)
    z = torch.randn(100, 3, dtype=torch.float64)
    grads = []
    for model in (net, plain):
        model.zero_grad()
        model(z).square().sum().backward()
        grads.append(torch.cat([p.grad.reshape(-1) for p in model.parameters()]))
    assert _close(grads[0], grads[1], rtol=1e-13)


def test_a_layer_that_is_not_linear_or_tanh_is_refused():
    with pytest.raises(TypeError, match="nn.Linear and nn.Tanh"):
        TanhNetwork(nn.Linear(2, 2, dtype=torch.float64), nn.ReLU())(torch.zeros(1, 2, dtype=torch.float64))
