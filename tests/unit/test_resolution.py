"""The step check: a fit's output must not depend on the RK4 step (torchpaml._fit.resolution).

A lightly damped Duffing oscillator (zeta = 0.05, omega0 = 2, k3 = 0.5) driven by pseudorandom knots
every 4 s for 200 s. The device is the continuous system: RK4 at 32 steps per sample (its error is far
below the noise). At h = 0.35 s (h omega0 = 0.7, Silverbox's) one RK4 step per sample is off by about
1 % of the output, more than a tenth of a 0.5 % misfit; at h = 0.035 s it is not.
"""


import pytest
import torch

from torchpaml import RK4, TRBDF2, Auto, Exact
from torchpaml import (
    ConstantForce,
    CubicStiffness,
    Oscillator,
    Record,
    ResolutionError,
    fit_physics,
    pseudorandom,
    simulate,
    time_grid,
)
from torchpaml.report import ranking_table
from torchpaml._fit import resolution
from torchpaml._simulate import solvers
from torchpaml._fit.resolution import STEP_TOLERANCE, step_gap

TRUTH = {"zeta": 0.05, "omega0": 2.0, "gain": 4.0, "cubic_stiffness.k3": 0.5}


def record(h: float, noise: float = 0.005) -> Record:
    t = time_grid(200.0, h)
    u = pseudorandom(t, 1.0, period=4.0, seed=0)
    device = Oscillator(zeta=0.05, omega0=2.0, gain=4.0) + CubicStiffness(0.5)
    with torch.no_grad():
        y = simulate(device, t, u, solver=RK4(substeps=32))[0]
    y = y + noise * y.std() * torch.randn(y.shape, generator=torch.Generator().manual_seed(7), dtype=torch.float64)
    return Record(t, u[0], y, f"h = {h:g} s")


def start() -> Oscillator:
    return Oscillator(zeta=0.06, omega0=2.1, gain=3.8, learn=("zeta", "omega0", "gain")) + CubicStiffness(0.4)


def test_the_fit_refines_the_step_until_its_output_no_longer_depends_on_it():
    coarse = record(0.35)
    model = start()
    fit = fit_physics(model, coarse)
    assert isinstance(fit.solver, RK4) and fit.solver.substeps >= 2
    assert step_gap(model, fit.solver, [coarse], [None]) <= STEP_TOLERANCE * fit.mismatch
    for name, truth in TRUTH.items():  # the intervals hold the truth once the step is resolved
        assert abs(fit.parameters[name] - truth) < 4 * fit.uncertainty.std[name], name


def test_without_the_check_the_step_error_biases_the_parameters_far_beyond_their_intervals(monkeypatch):
    # at one step per sample zeta is off by 23 standard errors, omega0 by 15 (measured); resolved, by 1
    monkeypatch.setattr(resolution, "STEP_TOLERANCE", float("inf"))
    fit = fit_physics(start(), record(0.35))
    assert fit.solver == RK4(substeps=1)
    assert abs(fit.parameters["zeta"] - TRUTH["zeta"]) > 10 * fit.uncertainty.std["zeta"]


def test_a_resolved_fit_keeps_one_step_per_sample():
    fit = fit_physics(start(), record(0.035))
    assert fit.solver == RK4(substeps=1)


def test_an_optimum_that_needs_more_substeps_than_allowed_is_refused_naming_the_fix(monkeypatch):
    monkeypatch.setattr(solvers, "MAX_SUBSTEPS", 1)
    with pytest.raises(ResolutionError, match=r"depends on the RK4 step.*Fit with solver=TRBDF2\(\).*bound that rate "
                                              r".* or sample faster"):
        fit_physics(start(), record(0.35), solver=RK4())
    # the default goes on with the implicit method, which does not resolve this smooth, non-stiff optimum either
    with pytest.raises(ResolutionError, match=r"depends on the TRBDF2 step"):
        fit_physics(start(), record(0.35))


def test_a_fit_of_a_model_built_on_a_fitted_one_starts_its_step_check_from_that_fit():
    assert Auto(start=RK4(substeps=4)).stepping() == RK4(substeps=4)
    assert Auto(start=Auto(start=TRBDF2(substeps=2))).stepping() == TRBDF2(substeps=2)
    # a fitted linear model: the exact path does not apply to physics + effect
    assert Auto(start=Exact()).stepping() == RK4(substeps=1)
    coarse = record(0.35)
    first = fit_physics(start(), coarse)
    again = fit_physics(start(), coarse, solver=Auto(start=first.solver))
    assert again.solver == first.solver
    assert again.parameters == pytest.approx(first.parameters, rel=1e-6)


def test_a_ranking_reports_an_unresolved_refit_and_does_not_recommend_it(monkeypatch):
    from torchpaml._diagnostics import rank_missing_effects

    monkeypatch.setattr(solvers, "MAX_SUBSTEPS", 1)
    train, validation = record(0.35).window(0, 400, "train"), record(0.35).window(400, None, "validation")
    linear = Oscillator(zeta=0.06, omega0=2.1, gain=3.8, learn=("zeta", "omega0", "gain"))
    ranking = rank_missing_effects(linear, [CubicStiffness(), ConstantForce()], train, validation, shortlist=1)
    shortlisted, other = ranking.entries  # none refitted: both by score, the shortlisted first
    assert shortlisted.refit is None and shortlisted.failure.startswith("refit unresolved: ")
    assert other.failure is None
    assert ranking.recommended is None
    assert "refit unresolved" in ranking_table(ranking)
