"""The selection rule's criterion at its edge: a fit that reproduces noise-free records exactly (sse 0)."""

import math

import pytest

from torchpaml import SelectionRule


def test_an_exact_fit_has_a_finite_criterion_below_any_inexact_one_and_the_penalty_decides_between_two():
    rule = SelectionRule()
    exact_two, exact_three = rule.value(0.0, 450, 2), rule.value(0.0, 450, 3)
    assert math.isfinite(exact_two) and math.isfinite(exact_three)
    assert exact_two < rule.value(1e-300, 450, 2)
    assert exact_three - exact_two == pytest.approx(rule.penalty(450, 3) - rule.penalty(450, 2), rel=1e-9)
