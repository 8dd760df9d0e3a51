"""The fleet's parameter spread and its severity order, on hand-made units (no Ray)."""

import numpy as np
import pytest

from torchpaml._diagnostics.analysis.spread import MAD_TO_STD, REACH, parameter_spread
from torchpaml._render.fleet import severity_order


def test_a_unit_beyond_the_fleets_reach_stands_out_and_the_spread_of_the_design_does_not():
    values = [2.00, 1.97, 2.03, 1.99, 2.02, 1.98, 2.01, 2.40]  # a 1.5 % spread and one unit 20 % off
    parameters = {f"u{i}": {"omega0": v, "zeta": 0.2} for i, v in enumerate(values)}
    uncertainty = {f"u{i}": {"omega0": 1e-3, "zeta": 1e-3} for i in range(len(values))}
    spreads = {s.name: s for s in parameter_spread(parameters, uncertainty)}
    omega0 = spreads["omega0"]
    assert omega0.outliers == ["u7"]
    assert omega0.median == pytest.approx(np.median(values))
    assert omega0.sigma == pytest.approx(MAD_TO_STD * np.median(np.abs(np.array(values) - np.median(values))))
    assert spreads["zeta"].outliers == []  # identical units: no spread, nothing stands out


def test_with_no_fleet_spread_a_units_own_standard_error_sets_its_reach():
    parameters = {"a": {"k": 1.0}, "b": {"k": 1.0}, "c": {"k": 1.0}, "d": {"k": 1.0 + 2.9 * REACH * 0.01},
                  "e": {"k": 1.0 + 3.1 * REACH * 0.01}}
    uncertainty = {u: {"k": 0.01 * (3 if u == "d" else 1)} for u in parameters}
    (spread,) = parameter_spread(parameters, uncertainty)
    assert spread.sigma == 0.0
    assert spread.outliers == ["e"]  # d is nearly as far, but its own larger standard error reaches the median


def test_parameters_of_fewer_than_three_units_are_left_out():
    parameters = {"a": {"k": 1.0, "effect.c": 0.5}, "b": {"k": 1.1}, "c": {"k": 0.9}}
    assert [s.name for s in parameter_spread(parameters, {})] == ["k"]


def row(unit, found=(), baseline=0.1, final=0.1, error=None):
    return {"unit": unit, "found": list(found), "nrmse_validation": {"baseline": baseline, "final": final},
            "error": error}


def test_severity_puts_failures_first_then_the_largest_gains():
    units = [row("ok"), row("small", ["x"], 0.10, 0.08), row("broken", error="DataError: ..."),
             row("large", ["y"], 0.20, 0.02)]
    assert [r["unit"] for r in severity_order(units)] == ["broken", "large", "small", "ok"]


def test_a_unit_whose_parameter_is_undetermined_is_never_its_outlier():
    parameters = {"a": {"k": 1.0}, "b": {"k": 1.1}, "c": {"k": 5.0}, "d": {"k": 1.05}}
    determined = {"a": {"k": 0.01}, "b": {"k": 0.01}, "c": {"k": 0.01}, "d": {"k": 0.01}}
    assert parameter_spread(parameters, determined)[0].outliers == ["c"]
    undetermined = {**determined, "c": {"k": None}}
    assert parameter_spread(parameters, undetermined)[0].outliers == []
