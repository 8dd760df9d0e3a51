"""The closed form that the compiled path and the exports are printed from, against the physics itself.

Oracle: the physics' own ``derivative`` and ``output`` in float64 at random rows (t, x, u), with every parameter
and buffer set to a random value, against the closed form in parameter symbols evaluated at the same numbers
(sympy's ``lambdify``). The form is made at other random values, so a parameter taken in as a number fails. Tolerance 1e-12 relative to the row's scale: the two are the same operations, evaluated in
another order. Cases: each library physics alone and with each library effect (hardening and friction, memory
effects with their own states, lags, sensor maps, kinks), and a user's two-output physics. The refusals: an in-place
operation, a number read out of a tensor, and a physics that raises.
"""

import numpy as np
import pytest
import sympy
import torch

from torchpaml import AbstractPhysics, ConfigurationError, PhysicalParameter, Positive, register_parameters
from torchpaml._physics.effects import EFFECTS
from torchpaml._physics.registry import PHYSICS
from torchpaml._symbolic.trace import symbolic_maps
from tests.two_mass import TwoMass

ROWS = 16


def _symbols(physics):
    """The twins: symbols for t, x, u and every parameter and buffer element; the same symbols flat, in order."""
    t = sympy.Symbol("t", real=True)
    x = [sympy.Symbol(f"x{i}", real=True) for i in range(physics.state_dim)]
    u = [sympy.Symbol(f"u{j}", real=True) for j in range(physics.input_dim)]
    tensors, flat = {}, []
    for name, tensor in (*physics.named_parameters(), *physics.named_buffers()):
        symbols = [sympy.Symbol(f"p{len(flat) + k}", real=True) for k in range(tensor.numel())]
        tensors[name] = np.array(symbols, dtype=object).reshape(tuple(tensor.shape))
        flat += symbols
    values = {"t": np.array([t], dtype=object), "x": np.array([x], dtype=object), "u": np.array([u], dtype=object)}
    return values, tensors, [t, *x, *u, *flat]


def _randomized(physics, generator):
    """``physics`` with each parameter and buffer at a random value near 1 (positive: buffers hold scales)."""
    with torch.no_grad():
        for tensor in (*physics.parameters(), *physics.buffers()):
            tensor.copy_(0.5 + torch.rand(tensor.shape, generator=generator, dtype=torch.float64))
    return physics


def _assert_matches_the_physics(physics, seed: int = 0):
    generator = torch.Generator().manual_seed(seed)
    values, tensors, arguments = _symbols(_randomized(physics, generator))
    rates, output = symbolic_maps(physics, values, tensors)
    physics = _randomized(physics, generator)
    evaluate = sympy.lambdify(arguments, [*rates.reshape(-1), *output.reshape(-1)], modules="numpy")
    t = torch.rand(ROWS, generator=generator, dtype=torch.float64)
    x = 2 * torch.rand(ROWS, physics.state_dim, generator=generator, dtype=torch.float64) - 1
    u = 2 * torch.rand(ROWS, physics.input_dim, generator=generator, dtype=torch.float64) - 1
    with torch.no_grad():
        expected = torch.cat([physics.derivative(t, x, u), physics.output(x, u)], dim=-1).numpy()
    numbers = [p.detach().reshape(-1).numpy() for p in (*physics.parameters(), *physics.buffers())]
    parameters = np.concatenate(numbers) if numbers else np.zeros(0)
    for row in range(ROWS):
        got = np.array(evaluate(t[row].item(), *x[row].numpy(), *u[row].numpy(), *parameters), dtype=float)
        scale = max(1.0, float(np.abs(expected[row]).max()))
        np.testing.assert_allclose(got, expected[row], rtol=0, atol=1e-12 * scale, err_msg=physics.display_name)


@pytest.mark.parametrize("name", sorted(PHYSICS))
def test_each_library_physics_alone(name):
    _assert_matches_the_physics(PHYSICS[name]())


@pytest.mark.parametrize("effect", sorted(EFFECTS))
@pytest.mark.parametrize("name", sorted(PHYSICS))
def test_each_library_effect_on_each_library_physics(name, effect):
    _assert_matches_the_physics(PHYSICS[name]() + EFFECTS[effect](), seed=len(effect))


def test_a_users_physics_with_two_outputs_and_an_effect_on_its_second_mass():
    _assert_matches_the_physics(TwoMass() + EFFECTS["coulomb_friction"]().on("v2"))


class _Spring(AbstractPhysics):
    """A spring written three ways that cannot be taken (:attr:`way`)."""

    state_names = ("x", "v")

    def __init__(self, way: str):
        super().__init__()
        self.way = way
        register_parameters(self, [PhysicalParameter("k", 1.0, "1/s^2", Positive(), "spring")], ("k",))

    def derivative(self, t, x, u):
        position, velocity = x.unbind(-1)
        force = u[..., 0] - self.k * position
        if self.way == "in place":
            force.sub_(0.3 * velocity)
        elif self.way == "item":
            force = force * (2.0 if position.sum().item() > 1.0 else 1.0)
        elif self.way == "raises":
            raise ValueError("the spring broke")
        return torch.stack([velocity, force], dim=-1)

    def output(self, x, u):
        return x[..., :1]


@pytest.mark.parametrize("way, message", [
    ("in place", r"cannot export .*: the exporter does not know the operation aten.sub_.Tensor; write the physics with "
                 r"the out-of-place operations"),
    ("item", r"cannot export .*: it reads a number out of a tensor \(.item\(\), float\(\), an if on a tensor\); "
             r"branch with torch.where"),
    ("raises", r"cannot export .*: its derivative or output fails on one row of zeros \(the spring broke\)"),
])
def test_what_cannot_be_taken_is_refused_in_one_line(way, message):
    physics = _Spring(way)
    values, tensors, _ = _symbols(physics)
    with pytest.raises(ConfigurationError, match=message):
        symbolic_maps(physics, values, tensors)
    assert physics.training, "the caller's mode is restored"
