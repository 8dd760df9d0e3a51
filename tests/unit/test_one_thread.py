"""One arithmetic path (``torchpaml._fit.one_thread``): a diagnosis started with two threads does every reduction on
one, its scores, fits, residuals and probes alike, and gives the threads back when it ends."""

import torch
from threadpoolctl import threadpool_info

from torchpaml import CoulombFriction, Oscillator, Prober, Simulated, diagnose
from torchpaml._diagnostics import diagnosis as diagnosis_module
from torchpaml._diagnostics.ranking import ranker as ranker_module


def _threads() -> tuple[int, int]:
    """torch's intra-op threads and the most threads any BLAS or OpenMP pool holds now."""
    return torch.get_num_threads(), max((pool["num_threads"] for pool in threadpool_info()), default=1)


def test_a_diagnosis_started_on_two_threads_scores_and_fits_on_one_and_gives_them_back(monkeypatch):
    seen = {}

    def spying(module, name):
        real = getattr(module, name)

        def spy(*args, **kwargs):
            seen.setdefault(name, []).append(_threads())
            return real(*args, **kwargs)
        monkeypatch.setattr(module, name, spy)

    spying(ranker_module, "scored")  # the first-order scores: outside every fit
    spying(ranker_module, "score_model")  # the rung's validation score
    spying(diagnosis_module, "_hybrid")  # the residual fits, in the diagnosis' own worker threads
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CoulombFriction(0.5)
    train = Simulated(truth, "pseudorandom", 1.0, [0], 20.0, 0.05, noise=0.01).experiments()
    validation = Simulated(truth, "multisine", 1.0, [1], 20.0, 0.05, noise=0.01).experiments()
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        diagnose(Oscillator(), [CoulombFriction()], train, validation, prober=Prober(), budget=None)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    assert set(seen) == {"scored", "score_model", "_hybrid"}
    assert all(threads == (1, 1) for calls in seen.values() for threads in calls), seen
