"""Physical parameters: constraints, fixing and learning, describe()."""

import pytest
import torch

from torchpaml import Interval, Oscillator, Positive


def test_constraints_round_trip():
    for constraint, value in [(Positive(), 0.37), (Interval(-1.0, 2.0), 1.5)]:
        raw = constraint.right_inverse(torch.tensor(value))
        assert float(constraint(raw)) == pytest.approx(value, rel=1e-14)


def test_only_named_parameters_are_learnable():
    physics = Oscillator(learn=("zeta", "gain"))
    assert physics.learnable_names() == ["zeta", "gain"]
    physics.set_learnable("gain", learn=False).set_learnable("omega0")
    assert physics.learnable_names() == ["zeta", "omega0"]


def test_assign_checks_constraints_and_names():
    physics = Oscillator()
    physics.assign(zeta=0.7)
    assert physics.physical_parameters()["zeta"] == pytest.approx(0.7)
    with pytest.raises(ValueError, match="must be positive"):
        physics.assign(zeta=-0.1)
    with pytest.raises(ValueError, match="no physical parameter 'mass'"):
        physics.assign(mass=1.0)
    with pytest.raises(ValueError, match="cannot learn unknown parameter"):
        Oscillator(learn=("mass",))


def test_describe_reports_units_constraints_and_status():
    text = Oscillator(zeta=0.25, omega0=3.0).describe()
    assert text.splitlines()[0] == "Oscillator"
    zeta = next(line for line in text.splitlines() if line.startswith("zeta"))
    assert "0.25" in zeta and "> 0" in zeta and "learned" in zeta
    omega0 = next(line for line in text.splitlines() if line.startswith("omega0"))
    assert "rad/s" in omega0 and "fixed" in omega0
