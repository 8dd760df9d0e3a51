"""A physics with two inputs: its records, the check of its channels, and the discovery of a force that reads both.

A tank with two feeds, $\\dot x = -a x + b_1 u_1 + b_2 u_2$, whose device mixes them, $+ 0.6\\,u_1 u_2$: the discovery's
variables are the state and every input (``x, u1, u2``), and it finds the product in closed form.
"""

import pytest
import torch

import torchpaml as tp

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane


class Mixer(tp.AbstractPhysics):
    """A tank with two feeds, ``u1`` and ``u2``; its level measured."""

    state_names = ("x",)
    input_dim = 2

    def __init__(self, a=1.0, b1=1.0, b2=1.0, *, learn=("a", "b1", "b2")):
        super().__init__()
        tp.register_parameters(self, [tp.PhysicalParameter("a", a, "1/s", tp.Positive(), "outflow rate"),
                                      tp.PhysicalParameter("b1", b1, "-", tp.Real(), "gain of feed 1"),
                                      tp.PhysicalParameter("b2", b2, "-", tp.Real(), "gain of feed 2")], learn)

    def derivative(self, t, x, u):
        return tp.state_vector([-self.a * x[..., 0] + self.b1 * u[..., 0] + self.b2 * u[..., 1]])

    def output(self, x, u):
        return x[..., :1]


def record(seed: int) -> tp.Record:
    truth = Mixer(0.8, 1.0, 0.5) + tp.DiscoveredForce(["u1*u2"], [0.6], ["x"])
    t = tp.time_grid(40.0, 0.05)
    u = torch.cat([tp.pseudorandom(t, 1.0, 0.5, seed=seed), tp.pseudorandom(t, 1.0, 0.7, seed=seed + 100)], dim=-1)
    with torch.no_grad():
        y = tp.simulate(truth, t, u)[0]
    noise = torch.randn(y.shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
    return tp.Record(t, u[0], y + 0.02 * y.std() * noise, f"feeds{seed}")


def test_the_discovery_reads_every_input_and_finds_their_product():
    assert tp.TermLibrary().build(Mixer()).count("u1*u2") == 1  # the library's terms read both inputs
    found = tp.diagnose(Mixer(), [], record(0), record(1), discovery=tp.Discoverer()).discovery
    assert found.recommended and found.effect is not None
    effect = found.effect
    assert effect.terms == ["u1*u2"]
    coefficient = float(effect.gain * getattr(effect, effect.parameter_names[0]))
    assert coefficient == pytest.approx(0.6, rel=0.02)  # measured 0.5999
