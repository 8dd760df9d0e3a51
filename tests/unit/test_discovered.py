"""The discovered force as a first-class effect, and the sparse regression that finds its terms."""

import math

import pytest
import torch
from jsonargparse import ArgumentParser

from torchpaml import AbstractEffect, candidate_terms, DiscoveredForce, Oscillator
from torchpaml._fit import select_support, stlsq
from torchpaml._physics.discovered import evaluate_term


def test_the_library_has_28_distinct_terms_that_all_evaluate():
    terms = candidate_terms()
    assert len(terms) == len(set(terms)) == 28
    x, v, u = (torch.linspace(-1, 1, 7, dtype=torch.float64) * s for s in (1.0, 2.0, 0.5))
    for term in terms:
        assert evaluate_term(term, x, v, u, 0.01).shape == x.shape
    assert {"1", "x", "v**3", "x**2*u", "x*u**2", "v*Abs(v)", "tanh(v/eps)", "x*tanh(v/eps)"} <= set(terms)


def test_terms_evaluate_to_their_formulas():
    x, v, u = torch.tensor([0.5, -1.0]), torch.tensor([-2.0, 0.3]), torch.tensor([1.5, -0.2])
    assert torch.allclose(evaluate_term("x**2*u", x, v, u, 0.1), x**2 * u)
    assert torch.allclose(evaluate_term("v*Abs(v)", x, v, u, 0.1), v * v.abs())
    assert torch.allclose(evaluate_term("v*u*Abs(v)", x, v, u, 0.1), v * u * v.abs())
    assert torch.allclose(evaluate_term("x*tanh(v/eps)", x, v, u, 0.1), x * torch.tanh(v / 0.1))
    assert torch.allclose(evaluate_term("1", x, v, u, 0.1), torch.ones(2))


@pytest.mark.parametrize("term", ["v^3", "w", "x*y", "u*x", "x**4", "x*x"])
def test_a_malformed_term_is_refused_with_the_grammar(term):
    with pytest.raises(ValueError, match=r"x, v, u, Abs\(v\), tanh\(v/eps\)"):
        DiscoveredForce([term], [1.0])


def test_one_coefficient_per_term():
    with pytest.raises(ValueError, match="one coefficient per term: 2 terms, 1 coefficients"):
        DiscoveredForce(["v**3", "x**2*u"], [1.0])


def test_added_with_plus_it_acts_as_its_formula_and_is_described():
    model = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + DiscoveredForce(["v**3", "x**2*u"], [-0.5, 0.25])
    x, v, u = torch.tensor([0.3]), torch.tensor([-1.2]), torch.tensor([0.7])
    expected = -2 * 0.2 * 2.0 * v - 4.0 * x + 4.0 * u - 0.5 * v**3 + 0.25 * x**2 * u
    assert torch.allclose(model.acceleration(torch.zeros(1), x, v, u), expected)
    table = model.describe()
    assert "discovered.c_v3" in table and "discovered.c_x2_u" in table and "coefficient of v**3" in table
    assert model.effects["discovered"].expression() == "-0.5*v**3 + 0.25*x**2*u"
    model.assign(**{"discovered.gain": 0.0})  # the strength switches it off
    assert torch.allclose(model.acceleration(torch.zeros(1), x, v, u), expected + 0.5 * v**3 - 0.25 * x**2 * u)


def test_the_config_block_rebuilds_the_same_force():
    force = DiscoveredForce(["tanh(v/eps)", "v*Abs(v)"], [-0.4, 0.1], eps=0.05)
    parser = ArgumentParser()
    parser.add_argument("--effect", type=AbstractEffect)
    rebuilt = parser.instantiate(parser.parse_object({"effect": force.to_config()})).effect
    assert isinstance(rebuilt, DiscoveredForce)
    assert rebuilt.terms_and_coefficients() == force.terms_and_coefficients() == [("tanh(v/0.05)", -0.4),
                                                                                 ("v*Abs(v)", 0.1)]
    assert set(rebuilt.values()) == {"gain", "c_tanhv", "c_v_absv", "eps"}
    by_name = {"effect": {**force.to_config(), "class_path": "DiscoveredForce"}}  # loaded by its class name alone
    assert parser.instantiate(parser.parse_object(by_name)).effect.expression() == force.expression()


def unit_library(samples=400, terms=12, seed=0):
    generator = torch.Generator().manual_seed(seed)
    A = torch.randn(samples, terms, generator=generator, dtype=torch.float64)
    return A / A.norm(dim=0), generator


def test_stlsq_and_bic_recover_a_sparse_support_from_noisy_data():
    A, generator = unit_library()
    b = 3.0 * A[:, 2] - 1.5 * A[:, 7]
    noisy = b + 0.02 * torch.randn(len(b), generator=generator, dtype=torch.float64)
    assert stlsq(A, noisy, threshold=0.2) == [2, 7]
    support, xi = select_support(A, noisy)
    assert support == [2, 7]
    assert xi.tolist() == pytest.approx([3.0, -1.5], abs=0.05)  # noise 0.02 per sample, unit columns: se ~0.02


def test_pure_noise_selects_the_empty_support():
    A, generator = unit_library(seed=1)
    noise = 0.02 * torch.randn(A.shape[0], generator=generator, dtype=torch.float64)
    support, xi = select_support(A, noise)
    assert support == [] and xi.numel() == 0
    assert not math.isnan(float(noise.norm()))
