"""The verdict on a long record decides by effect size: right physics with coloured sensor noise is complete."""

import pytest
import torch

from torchpaml import Oscillator, Simulated, diagnose

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane


def coloured(record, share: float, pole: float, seed: int):
    """``record`` with AR(1) sensor noise (pole ``pole``) of RMS ``share`` of the output's RMS added."""
    generator = torch.Generator().manual_seed(seed)
    white = torch.randn(len(record.t), generator=generator, dtype=torch.float64)
    noise = torch.zeros_like(white)
    for k in range(1, len(white)):  # a sensor's low-pass: pole 0.9, ~10 samples of memory
        noise[k] = pole * noise[k - 1] + white[k]
    noise = noise / noise.square().mean().sqrt() * share * record.y.square().mean().sqrt()
    record.y = record.y + noise[:, None]
    return record


def test_right_physics_with_coloured_noise_on_50_000_samples_is_complete():
    truth = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=())
    train = coloured(Simulated(truth, "pseudorandom", 1.0, [0], 2500.0, 0.05).experiments()[0], 0.02, 0.9, 0)
    validation = coloured(Simulated(truth, "multisine", 1.0, [1], 2500.0, 0.05).experiments()[0], 0.02, 0.9, 1)
    assert len(train.t) >= 50_000
    diagnosis = diagnose(Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain")), [], train,
                         validation)
    adequacy = diagnosis.hybrids[-1].adequacy
    assert not adequacy.inadequate, adequacy.message
    assert adequacy.message.startswith("physics complete at this noise level"), adequacy.message
    assert "--discover" not in diagnosis.verdict
