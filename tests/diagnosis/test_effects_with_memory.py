"""Effects with memory in the whole diagnosis: the lag that a Chebyshev residual would cover.

The hidden-effect oscillator (``test_hidden_effects.py``) with a 6-sample input lag, on multisine records
for training and validation (the regime where the residual, a filter of the input, generalises).
"""

import torch

from torchpaml import Simulated, default_effects, diagnose

from test_hidden_effects import CASES, physics, truth


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
