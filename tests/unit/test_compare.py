"""``compare``: scores per experiment and model, against the metric definitions."""

import pytest

from torchpaml import Oscillator, Record, pseudorandom, time_grid
from torchpaml.analysis import compare
from torchpaml.figures import comparison_figure
from torchpaml.report import comparison_table


@pytest.fixture
def record():
    t = time_grid(20.0, 0.01)
    u = pseudorandom(t, 1.0, seed=5)
    y = Oscillator(zeta=0.3)(t, u).detach()
    return Record(t, u[0], y[0], "prbs")


def test_the_true_model_scores_perfectly_and_a_wrong_one_does_not(record):
    result = compare({"truth": Oscillator(zeta=0.3), "wrong": Oscillator(zeta=0.6)}, record)
    truth, wrong = result.rows
    assert truth["mismatch_pct"] < 1e-10 and truth["fit_pct"] == pytest.approx(100.0) and truth["rmse"] < 1e-12
    t, u, y = record.batch()
    y_wrong = Oscillator(zeta=0.6)(t, u).detach()
    assert wrong["rmse"] == pytest.approx(float((y - y_wrong).pow(2).mean().sqrt()), rel=1e-12)
    assert wrong["fit_pct"] == pytest.approx(100 * (1 - float((y - y_wrong).norm() / (y - y.mean()).norm())), rel=1e-12)
    assert "| prbs | wrong |" in comparison_table(result)
    assert "truth (100.0 % fit)" in [line.get_label() for line in comparison_figure(result).axes[0].lines]


def test_experiment_names_must_differ(record):
    with pytest.raises(ValueError, match="names must differ"):
        compare({"m": Oscillator()}, [record, record])
