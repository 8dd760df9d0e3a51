"""The Lightning systems against the library's own fitting functions, on the paper's problem (shortened)."""

import lightning as L
import pytest
import torch

from torchpaml import (
    ChebyshevHammerstein,
    Record,
    RecordDataModule,
    fit_chebyshev_hammerstein,
    fit_physics,
    JointFit,
    mismatch,
    Oscillator,
    Pendulum,
    PhysicsFit,
    ResidualFit,
    Simulated,
)

PENDULUM = dict(system=Pendulum(zeta=0.5, omega0=2.0, learn=()), amplitude=4.0, duration=40.0)


def train(system, data, epochs):
    trainer = L.Trainer(max_epochs=epochs, logger=False, enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, num_sanity_val_steps=0)
    trainer.fit(system, data)
    return system


@pytest.fixture(scope="module")
def paper_data():
    return RecordDataModule(
        train=Simulated(signal="pseudorandom", seeds=[0], **PENDULUM),
        validation=Simulated(signal="pseudorandom", seeds=[1], **PENDULUM),
        identification=Simulated(signal="sine", **PENDULUM),
    )


@pytest.fixture(scope="module")
def zeta_hat(paper_data):
    t, u, y = paper_data.records("identification")[0].batch()
    return fit_physics(Oscillator(zeta=1.0), Record.records(t, u, y), bounds={"zeta": (1e-3, 5.0)}).parameters["zeta"]


def test_lightning_physics_fit_matches_fit_physics(paper_data, zeta_hat):
    data = RecordDataModule(train=paper_data.sources["identification"])
    system = train(PhysicsFit(Oscillator(zeta=1.0), bounds={"zeta": (1e-3, 5.0)}), data, epochs=3)
    assert system.physics.zeta.item() == pytest.approx(zeta_hat, rel=1e-6)


def test_residual_fit_matches_the_library_two_stage_fit(paper_data, zeta_hat):
    system = train(ResidualFit(Oscillator(zeta=1.0), ChebyshevHammerstein(4.0), bounds={"zeta": (1e-3, 5.0)}),
                   paper_data, epochs=5)
    assert system.physics.zeta.item() == pytest.approx(zeta_hat, rel=1e-6)
    t, u, y = paper_data.records("train")[0].batch()
    physics = Oscillator(zeta=zeta_hat)
    with torch.no_grad():
        target = y - physics(t, u)
    reference = ChebyshevHammerstein(4.0)
    fit_chebyshev_hammerstein(reference, t, u, target)
    lightning = system.record_mismatch(paper_data.records("train"))
    library = mismatch(y, physics(t, u) + reference(t, u))
    assert lightning == pytest.approx(library, rel=0.05)  # two runs of a non-convex pole fit
    assert lightning < 0.5 * mismatch(y, physics(t, u))


@pytest.mark.slow
@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_joint_fit_with_the_chebyshev_residual_returns_to_the_physics_estimate(paper_data, zeta_hat, factor):
    sine = paper_data.sources["identification"]
    data = RecordDataModule(train=sine)
    residual = ChebyshevHammerstein(4.0)
    system = train(JointFit(Oscillator(zeta=factor * zeta_hat), residual, bounds={"zeta": (1e-3, 5.0)}), data, 4)
    assert system.physics.zeta.item() == pytest.approx(zeta_hat, rel=0.01)  # the 1 %


def test_both_stages_train_a_physics_with_two_outputs():
    """A user's two-mass chain (tests/two_mass.py), both positions measured: stage 1 recovers its parameters, stage 2
    fits a residual with an output per channel."""
    from two_mass import TRUTH, TwoMass

    sources = {split: Simulated(TwoMass(**TRUTH), signal, 1.0, [seed], 20.0, 0.02, noise=0.01)
               for split, signal, seed in (("train", "pseudorandom", 0), ("validation", "multisine", 1),
                                           ("identification", "pseudorandom", 2))}
    data = RecordDataModule(**sources)
    physics = train(PhysicsFit(TwoMass()), RecordDataModule(train=sources["identification"]), epochs=2).physics
    assert physics.physical_parameters() == pytest.approx(TRUTH, rel=0.01)
    system = train(ResidualFit(TwoMass(), ChebyshevHammerstein(1.05, outputs=2)), data, epochs=2)
    t, u, _ = data.records("train")[0].batch()
    with torch.no_grad():
        assert system.residual(t, u).shape == (1, len(t), 2)
