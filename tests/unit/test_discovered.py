"""Discovered terms as a first-class effect: the sympy grammar, the generated library, the sparse regression."""

import pytest
import torch
from jsonargparse import ArgumentParser

from torchpaml import AbstractEffect, AbstractPhysics, DiscoveredForce, Oscillator, SparseRegression, TermLibrary
from torchpaml import state_vector
from torchpaml._fit import stlsq
from torchpaml._physics.terms import compile_term


class Tank(AbstractPhysics):
    state_names = ("level",)

    def derivative(self, t, x, u):
        return state_vector([u[..., 0] - 0.5 * x[..., 0]])

    def output(self, x, u):
        return x[..., :1]


def test_the_generated_library_covers_products_signs_and_roots():
    terms = TermLibrary().build(Oscillator())
    assert len(terms) == len(set(terms)) == 42  # 20 monomials, 2 x 10 sign-like products, 2 roots
    assert {"1", "x", "v**3", "u*x**2", "u**2*x", "v*Abs(v)", "tanh(v/eps)", "x**2*tanh(v/eps)",
            "sqrt(Abs(x))"} <= set(terms)
    tank = TermLibrary(terms=("level*sign(u)",)).build(Tank())
    assert {"sqrt(Abs(level))", "level*tanh(level/eps_level)", "level*u**2", "level*sign(u)"} <= set(tank)
    x, v, u = (torch.linspace(-1, 1, 7, dtype=torch.float64) * s for s in (1.0, 2.0, 0.5))
    for term in terms:
        assert compile_term(term, ("x", "v", "u")).evaluate({"x": x, "v": v, "u": u, "eps": 0.01}).shape == x.shape


def test_terms_evaluate_to_their_formulas():
    x, v, u = torch.tensor([0.5, -1.0]), torch.tensor([-2.0, 0.3]), torch.tensor([1.5, -0.2])
    values = {"x": x, "v": v, "u": u, "eps": torch.tensor(0.1)}

    def value(term):
        return compile_term(term, ("x", "v", "u")).evaluate(values)

    assert torch.allclose(value("x**2*u"), x**2 * u)
    assert torch.allclose(value("v*Abs(v)"), v * v.abs())
    assert torch.allclose(value("x**2*sign(v)"), x**2 * v.sign())
    assert torch.allclose(value("sqrt(Abs(x))"), x.abs().sqrt())
    assert torch.allclose(value("x*tanh(v/eps)"), x * torch.tanh(v / 0.1))
    assert torch.allclose(value("1"), torch.ones(2))
    assert compile_term("u*x*x", ("x", "v", "u")).text == "u*x**2"  # sympy's canonical spelling


@pytest.mark.parametrize("term, message", [("w", r"uses \['w'\], which are not variables"),
                                           ("x +", "is not an expression"),
                                           ("floor(x)", r"the call floor\(\.\.\.\) is not allowed in a term"),
                                           ("2", "is a number")])
def test_a_malformed_term_is_refused_with_the_fix(term, message):
    with pytest.raises(ValueError, match=message):
        DiscoveredForce([term], [1.0])


def test_one_coefficient_per_term():
    with pytest.raises(ValueError, match="one coefficient and one equation per term: 2 terms, 1 coefficients"):
        DiscoveredForce(["v**3", "x**2*u"], [1.0])


def test_added_with_plus_it_acts_as_its_formula_and_is_described():
    model = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + DiscoveredForce(["v**3", "x**2*u"], [-0.5, 0.25])
    x, v, u = torch.tensor([0.3]), torch.tensor([-1.2]), torch.tensor([0.7])
    expected = -2 * 0.2 * 2.0 * v - 4.0 * x + 4.0 * u - 0.5 * v**3 + 0.25 * x**2 * u
    assert torch.allclose(model.acceleration(torch.zeros(1), x, v, u), expected)
    table = model.describe()
    assert "discovered.c_v3" in table and "discovered.c_u_x2" in table and "coefficient of v**3" in table
    assert model.effects["discovered"].expression() == "-0.5*v**3 + 0.25*u*x**2"
    model.assign(**{"discovered.gain": 0.0})  # the strength switches it off
    assert torch.allclose(model.acceleration(torch.zeros(1), x, v, u), expected + 0.5 * v**3 - 0.25 * x**2 * u)


def test_on_first_order_physics_a_term_adds_to_its_state_equation():
    model = Tank() + DiscoveredForce(["sqrt(Abs(level))"], [-0.8], equations=["level"])
    x, u = torch.tensor([[4.0], [0.25]], dtype=torch.float64), torch.tensor([[1.0], [0.0]], dtype=torch.float64)
    assert torch.allclose(model.derivative(torch.zeros(2), x, u)[:, 0],
                          torch.tensor([1 - 2.0 - 0.8 * 2, -0.125 - 0.8 * 0.5], dtype=torch.float64))
    assert model.effects["discovered"].expression() == "-0.8*sqrt(Abs(level))"
    with pytest.raises(TypeError, match=r"equation\(s\) \['acceleration'\]"):
        Tank() + DiscoveredForce(["v**3"], [1.0])


def test_several_equations_print_one_expression_each():
    force = DiscoveredForce(["sqrt(Abs(upper))", "sqrt(Abs(upper))"], [-0.5, 0.5], equations=["upper", "lower"])
    assert force.expression() == {"upper": "-0.5*sqrt(Abs(upper))", "lower": "0.5*sqrt(Abs(upper))"}


def test_an_output_term_adds_to_the_output_of_the_states_and_input_and_leaves_the_rates():
    base = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=())
    model = base + DiscoveredForce(["x*u", "v", "1"], [0.3, -0.1, 0.05], equations=["output"] * 3)
    x = torch.tensor([[0.3, -1.2], [1.0, 0.5]], dtype=torch.float64)
    u = torch.tensor([[0.7], [-2.0]], dtype=torch.float64)
    assert torch.equal(model.derivative(torch.zeros(2), x, u), base.derivative(torch.zeros(2), x, u))
    expected = x[:, 0] + 0.3 * x[:, 0] * u[:, 0] - 0.1 * x[:, 1] + 0.05
    assert torch.allclose(model.output(x, u)[:, 0], expected)
    assert model.equation() == "Oscillator y -> y + c_u_x*u*x + c_v*v + c_1*1"
    assert model.effects["discovered"].expression() == "0.3*u*x - 0.1*v + 0.05"
    model.assign(**{"discovered.gain": 0.0})  # the strength switches it off
    assert torch.allclose(model.output(x, u), base.output(x, u))


def test_an_output_term_on_a_physics_with_two_outputs_is_refused():
    from two_mass import TwoMass

    with pytest.raises(TypeError, match="add to a single output; TwoMass has 2"):
        TwoMass() + DiscoveredForce(["x1"], [1.0], equations=["output"])


def test_the_config_block_rebuilds_the_same_force():
    force = DiscoveredForce(["tanh(v/eps)", "v*Abs(v)"], [-0.4, 0.1], eps=0.05)
    parser = ArgumentParser()
    parser.add_argument("--effect", type=AbstractEffect)
    rebuilt = parser.instantiate(parser.parse_object({"effect": force.to_config()})).effect
    assert isinstance(rebuilt, DiscoveredForce)
    assert rebuilt.terms_and_coefficients() == force.terms_and_coefficients() == [
        ("tanh(v/0.05)", -0.4, "acceleration"), ("v*Abs(v)", 0.1, "acceleration")]
    assert set(rebuilt.values()) == {"gain", "c_tanh_v_eps", "c_v_Abs_v", "eps"}
    by_name = {"effect": {**force.to_config(), "class_path": "DiscoveredForce"}}  # loaded by its class name alone
    assert parser.instantiate(parser.parse_object(by_name)).effect.expression() == force.expression()


def unit_library(samples=400, terms=12, seed=0):
    generator = torch.Generator().manual_seed(seed)
    A = torch.randn(samples, terms, generator=generator, dtype=torch.float64)
    return A / A.norm(dim=0), generator


def test_stlsq_and_the_extended_bic_recover_a_sparse_support_from_noisy_data():
    A, generator = unit_library()
    b = 3.0 * A[:, 2] - 1.5 * A[:, 7]
    noisy = b + 0.02 * torch.randn(len(b), generator=generator, dtype=torch.float64)
    assert stlsq(A, noisy, threshold=0.2) == [2, 7]
    assert SparseRegression().select(A, noisy) == [2, 7]
    assert SparseRegression(max_terms=1).select(A, noisy) == [2]


def test_pure_noise_selects_the_empty_support():
    A, generator = unit_library(seed=1)
    noise = 0.02 * torch.randn(A.shape[0], generator=generator, dtype=torch.float64)
    assert SparseRegression().select(A, noise) == []


def test_a_term_whose_column_repeats_an_earlier_one_is_left_out_and_the_earlier_spelling_kept():
    from torchpaml._diagnostics.discovery.closed_form_search import _distinct

    generator = torch.Generator().manual_seed(0)
    a, b, c = (torch.randn(500, dtype=torch.float64, generator=generator) for _ in range(3))
    columns = torch.stack([a, 2 * a, b, -b, c, a + 1e-3 * c], dim=1)
    unit = columns / columns.norm(dim=0)
    assert _distinct([0, 1, 2, 3, 4, 5], unit) == [0, 2, 4, 5]  # 2a and -b repeat a and b; a + 1e-3 c does not
    assert _distinct([1, 0, 3], unit) == [1, 3]  # the order given decides which spelling stays
    assert _distinct([], unit) == []
