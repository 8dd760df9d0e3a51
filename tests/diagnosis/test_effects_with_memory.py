"""Effects with memory in the whole diagnosis: the lag that a Chebyshev residual would cover.

The hidden-effect oscillator (``test_hidden_effects.py``) with a 6-sample input lag, on multisine records
for training and validation (the regime where the residual, a filter of the input, generalises).
"""

import pytest

import math

import torch

from torchpaml._diagnostics.ranking import refits as refits_module

from torchpaml import ConstantForce, InputLag, QuadraticStiffness, Simulated, default_effects, diagnose
from torchpaml.analysis import rank_missing_effects

from test_hidden_effects import CASES, physics, records, truth

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane


def lagged_records():
    strength, amplitude = CASES["input_lag"]
    system = truth("input_lag", strength)
    return [Simulated(system, "multisine", amplitude, [seed], 30.0, 0.05, noise=0.02).experiments()[0]
            for seed in (0, 1)]


def test_without_the_lag_the_adequate_hybrid_says_it_may_be_covering_a_dynamic_effect():
    torch.manual_seed(0)
    train, validation = lagged_records()
    verdict = diagnose(physics(), [], train, validation).hybrids[0]
    assert verdict.physics_validation > 5 * 0.02  # the physics alone stays far off (20 %)
    assert not verdict.adequacy.inadequate and verdict.adequacy.covering, verdict.adequacy.message


def test_with_the_lag_among_the_candidates_the_ladder_adds_it_and_the_caveat_goes():
    torch.manual_seed(0)
    train, validation = lagged_records()
    diagnosis = diagnose(physics(), default_effects(), train, validation)
    assert diagnosis.ladder.added == ["input_lag"]
    assert diagnosis.ladder.final.nrmse_validation < 1.5 * 0.02
    assert not diagnosis.hybrids[-1].adequacy.covering


def test_a_lag_the_data_do_not_have_is_a_failed_refit_not_a_failed_diagnosis(monkeypatch):
    """On the oscillator with its constant force already found, the data hold no lag: its first-order score
    cannot pass the rule, so it is not refitted. Refitted all the same (the gate opened), it drives tau towards 0,
    a rate at the edge of what RK4's step integrates (a difference's side past it is one-sided, a step beyond it
    rejected): the refit ends with finite parameters, improves nothing and is not recommended, and the ranking goes
    on."""
    train, validation, _ = records(truth("constant_force", 0.5), 1.0)
    physics_with_force = (physics() + ConstantForce()).assign(**{"constant_force.f0": 0.5})
    gated = rank_missing_effects(physics_with_force, [InputLag()], train, validation)
    assert gated.entries[0].refit is None and "first-order score" in gated.entries[0].refit_reason
    monkeypatch.setattr(refits_module, "GATE_MARGIN", math.inf)
    ranking = rank_missing_effects(physics_with_force, [InputLag(), QuadraticStiffness()], train, validation,
                                   shortlist=2, refit_budget=1000.0)  # the stiff refit's whole path, not its budget
    lag = next(e for e in ranking.entries if e.effect == "input_lag")
    assert lag.failure is None and lag.improvement < 0, (lag.failure, lag.improvement)
    assert all(math.isfinite(v) for v in lag.refit.parameters.values()), lag.refit.parameters
    assert ranking.recommended is None  # and the other candidate was refitted, and not accepted
    assert next(e for e in ranking.entries if e.effect == "quadratic_stiffness").refit is not None
