"""A fit's budget: progress lines while it runs, OverBudget past its limit; the ranking's gate and undecided refits."""

import logging
import math
import time

import pytest
import torch

from torchpaml import (
    Budget,
    CubicStiffness,
    Oscillator,
    OverBudget,
    RK4,
    Record,
    SelectionRule,
    fit_physics,
    pseudorandom,
    simulate,
    time_grid,
)
from torchpaml.analysis import rank_missing_effects
from torchpaml._diagnostics.ranking.refits import GATE_MARGIN, cannot_pass
from torchpaml import _budget as budget_module


@pytest.fixture(scope="module")
def duffing():
    """Training and validation records of a Duffing oscillator with 1 % noise (20 s at 20 Hz)."""
    t = time_grid(20.0, 0.05)
    true = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CubicStiffness(2.0)
    made = []
    for seed in (0, 1):
        u = pseudorandom(t, 1.0, seed=seed)
        y = simulate(true, t, u, solver=RK4(substeps=4))[0].detach()
        noise = 0.01 * y.pow(2).mean().sqrt() * torch.randn(y.shape, generator=torch.Generator().manual_seed(seed))
        made.append(Record(t, u[0], y + noise, f"seed{seed}"))
    return made


def nonlinear_start():
    return Oscillator(zeta=0.3, omega0=1.8, gain=3.0, learn=()) + CubicStiffness(1.0)


def test_a_fit_past_its_budget_stops_with_the_time_it_ran(duffing):
    model = nonlinear_start().set_learnable("zeta", "omega0", "gain", "cubic_stiffness.k3")
    with pytest.raises(OverBudget, match="over its budget") as stopped:
        fit_physics(model, duffing[0], budget=Budget("a test fit", seconds=0.0, evaluations=0.0))
    assert 0 < stopped.value.seconds < 60


def test_the_limit_counts_evaluations_and_the_wall_clock_is_a_safety_net():
    budget = Budget("x", seconds=1e6, evaluations=3.0)
    budget.check(0.5, evaluation_seconds=0.3)
    budget.check(0.5, evaluation_seconds=9.0)  # a slow evaluation does not count more than a fast one
    with pytest.raises(OverBudget, match="after 3 evaluations .*budget 3 evaluations"):
        budget.check(0.5, evaluation_seconds=0.1)
    assert Budget("x", seconds=1.0).limit == 1.0
    capped = Budget("y", seconds=100.0, deadline=time.perf_counter() + 2.0)
    capped.check(0.5, evaluation_seconds=0.1)
    assert capped.limit <= 2.0 and not capped.expired
    assert Budget("z", deadline=time.perf_counter() - 1.0).expired
    assert Budget("free").limit == math.inf


def test_a_long_fit_prints_its_progress(duffing, caplog, monkeypatch):
    monkeypatch.setattr(budget_module, "PROGRESS_SECONDS", 0.0)  # a line at every evaluation
    model = nonlinear_start().set_learnable("zeta", "omega0", "gain", "cubic_stiffness.k3")
    with caplog.at_level(logging.INFO, logger="torchpaml._budget"):
        estimate = fit_physics(model, duffing[0], budget=Budget("fitting the Duffing"))
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("fitting the Duffing")]
    assert len(lines) == estimate.evaluations, lines
    assert "evaluations, cost" in lines[-1]
    costs = [float(line.split("cost ")[1].split(",")[0]) for line in lines]
    assert costs == sorted(costs, reverse=True)  # the lowest cost so far: it never rises
    assert costs[-1] == pytest.approx(0.5 * estimate.mismatch**2, rel=1e-5)  # printed to 6 digits


def test_the_gate_refits_what_could_pass_the_rule_at_its_margin():
    rule = SelectionRule()  # needs a 5 % fall of the validation mismatch: 9.75 % of the residual's energy
    model, base = Oscillator() + CubicStiffness(), Oscillator()
    records = [Record(time_grid(10.0, 0.05), torch.zeros(200, 1), torch.ones(200, 1), "r")]
    needed = 1 - (1 - rule.min_share) ** 2
    assert cannot_pass(1.01 * needed / GATE_MARGIN, rule, records, model, base) is None
    why = cannot_pass(0.99 * needed / GATE_MARGIN, rule, records, model, base)
    assert why is not None and "fall of the validation mismatch" in why and "needs 5 %" in why
    strict = SelectionRule(threshold=1e6, min_share=0.0)  # the criterion gain is the binding part
    assert "criterion gain" in cannot_pass(0.5, strict, records, model, base)


def test_a_refit_over_its_budget_is_undecided_and_says_why(duffing):
    train, validation = duffing
    ranking = rank_missing_effects(Oscillator(zeta=0.3, omega0=1.8, gain=3.0), [CubicStiffness()], train, validation,
                                   refit_budget=1e-9)
    (entry,) = ranking.entries
    assert entry.refit is None and entry.undecided is not None and entry.undecided > 0
    assert entry.refit_reason == f"undecided: over budget ({entry.undecided:.1f} s)"
    assert ranking.undecided == [entry] and ranking.recommended is None
    generous = rank_missing_effects(Oscillator(zeta=0.3, omega0=1.8, gain=3.0), [CubicStiffness()], train, validation)
    assert generous.recommended is not None and generous.recommended.refit_reason.startswith("refitted")


def test_an_evaluation_that_runs_away_inside_the_engine_stops_at_the_next_newton_sweep(duffing, monkeypatch):
    """The active budget's wall clock is enforced inside the shooting engine, not only between evaluations."""
    from torchpaml._simulate import compiled, shooting

    monkeypatch.setattr(compiled, "compiler", lambda: None)  # the engine, whose Newton sweeps check the clock
    monkeypatch.setattr(compiled, "_WARNED", {"no C compiler (cc, gcc) is on PATH; install one"})
    monkeypatch.setattr(compiled, "_FORMS", compiled.OrderedDict())
    original = shooting._Sweep

    def slow_sweep(*args, **kwargs):  # from the second evaluation on, the wall clock runs out at the first sweep
        if budget.count >= 1:
            time.sleep(0.05)
            budget.seconds = 0.0
        return original(*args, **kwargs)

    monkeypatch.setattr(shooting, "_Sweep", slow_sweep)
    budget = Budget("a runaway")
    model = nonlinear_start().set_learnable("zeta", "omega0", "gain", "cubic_stiffness.k3")
    with pytest.raises(OverBudget, match="wall clock"):
        fit_physics(model, duffing[0], budget=budget)
    assert budget.count == 1  # stopped inside the second evaluation, before it ended


def test_a_refits_evaluations_are_ten_times_its_rungs_fit_and_never_fewer_than_ten_of_its_own_limits():
    from torchpaml._budget import refit_evaluations

    assert refit_evaluations(10.0, 7, 40) == 400  # a rung fitted from its refit's optimum in a few evaluations
    assert refit_evaluations(10.0, 6, 40) == refit_evaluations(10.0, 7, 40)  # the tanks' 6 or 7: the same limit
    assert refit_evaluations(10.0, 55, 40) == 550
