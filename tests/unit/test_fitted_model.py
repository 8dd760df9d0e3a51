"""A fitted model travels with its solver: ``fit.model.simulate(record)`` is the output the fit scored."""

import pytest
import torch

from torchpaml import CubicStiffness, Estimate, Oscillator, Record, Rest, fit_physics, mismatch, pseudorandom, simulate
from torchpaml import time_grid
from torchpaml.analysis import rank_missing_effects


def _record(x0=None) -> Record:
    t = time_grid(20.0, 0.05)
    u = pseudorandom(t, 1.0, seed=0)
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(1.5)
    with torch.no_grad():
        y = simulate(truth, t, u, x0)
    noise = 0.01 * y.std() * torch.randn(y.shape, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    return Record(t, u[0], (y + noise)[0])


@pytest.mark.parametrize("policy", [Rest(), Estimate()])
def test_the_fitted_model_simulates_a_record_as_the_fit_did(policy):
    record = _record(torch.tensor([[0.3, -0.2]], dtype=torch.float64))
    model = Oscillator(learn=("zeta", "omega0", "gain")) + CubicStiffness(1.0)
    fit = fit_physics(model, record, initial_state=policy)
    assert fit.model.physics is model and fit.model.solver == fit.solver and fit.solver.stepping() is not None
    y = fit.model.simulate(record, fit.initial_states[0])
    assert float(mismatch(record.y, y)) == pytest.approx(fit.mismatch, rel=1e-6)
    assert fit.model.states(record, fit.initial_states[0]).shape == (len(record.t), 2)


def test_a_ranked_model_simulates_as_it_was_scored():
    record = _record()
    train, validation = record.window(0, 250, "train"), record.window(250, None, "validation")
    ranking = rank_missing_effects(Oscillator(learn=("zeta", "omega0", "gain")), [CubicStiffness()], train, validation)
    best = ranking.entries[0].refit
    y = best.fitted.simulate(validation)
    assert float(mismatch(validation.y, y)) == pytest.approx(best.nrmse_validation, rel=1e-6)
