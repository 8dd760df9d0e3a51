"""Records with missing samples (non-uniform time): the ranking simulates them directly; diagnose refuses at once."""

import pytest
import torch

from torchpaml import CoulombFriction, DataError, Oscillator, Record, Simulated, default_effects, diagnose
from torchpaml.analysis import rank_missing_effects

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane


@pytest.fixture(scope="module")
def gappy():
    """Every third sample of a hidden-Coulomb-friction record dropped (45 s at 20 Hz -> 600 samples)."""
    true = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CoulombFriction(0.5)
    made = []
    for signal, seed in (("pseudorandom", 0), ("multisine", 1)):
        record = Simulated(true, signal, 1.0, [seed], 45.0, 0.05, noise=0.02).experiments()[0]
        keep = torch.arange(len(record.t)) % 3 != 2
        made.append(Record(record.t[keep], record.u[keep], record.y[keep], f"{signal}-gaps"))
    return made


def _physics():
    return Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain"))


def test_the_ranking_finds_the_hidden_effect_on_records_with_missing_samples(gappy):
    ranking = rank_missing_effects(_physics(), default_effects(), *gappy, shortlist=2)
    assert ranking.recommended is not None and ranking.recommended.effect == "coulomb_friction"
    assert ranking.recommended.refit.parameters["coulomb_friction.Fc"] == pytest.approx(0.5, rel=0.1)


def test_diagnose_refuses_missing_samples_before_any_work_and_names_the_gaps(gappy, monkeypatch):
    def no_fit(*args, **kwargs):
        raise AssertionError("diagnose fitted a model before checking the time axis")

    monkeypatch.setattr("torchpaml._diagnostics.ranking.steps.fit_physics", no_fit)
    with pytest.raises(DataError, match=r"299 of its 599 steps differ .* first between t = 0.05 and 0.15 s.*resample"):
        diagnose(_physics(), default_effects(), *gappy)
