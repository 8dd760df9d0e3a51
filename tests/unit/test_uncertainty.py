"""Parameter uncertainty: intervals that cover the truth at their nominal rate, and the identifiability warning."""

import pytest
import torch

from torchpaml import (
    AbstractPhysics,
    Record,
    fit_physics,
    IdentifiabilityWarning,
    Oscillator,
    PhysicalParameter,
    Positive,
    pseudorandom,
    register_parameters,
    time_grid,
)

TRUTH = {"zeta": 0.2, "omega0": 2.0, "gain": 4.0}


def _noisy_record(seed: int) -> Record:
    t = time_grid(15.0, 0.05)
    u = pseudorandom(t, 1.0, seed=seed)
    generator = torch.Generator().manual_seed(1000 + seed)
    with torch.no_grad():
        y = Oscillator(**TRUTH)(t, u)
    return Record(t, u[0], y[0] + 0.05 * torch.randn(y[0].shape, generator=generator), name=f"seed {seed}")


def test_95_percent_intervals_cover_the_truth_at_their_nominal_rate():
    """50 seeds x 3 parameters = 150 intervals; 95 % coverage expects 142.5, binomial std 2.7.

    Accepting 0.90 to 0.99 (135 to 148) leaves about 2.8 standard deviations below and 2.1 above.
    """
    covered, total = 0, 0
    for seed in range(50):
        model = Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=tuple(TRUTH))
        fit = fit_physics(model, _noisy_record(seed))
        for name, (lower, upper) in fit.uncertainty.interval.items():
            covered += lower <= TRUTH[name] <= upper
            total += 1
    assert 0.90 <= covered / total <= 0.99, f"coverage {covered}/{total}"


def test_the_standard_error_shrinks_like_one_over_root_n():
    model = Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=tuple(TRUTH))
    short = fit_physics(model, _noisy_record(0)).uncertainty.std["zeta"]
    records = [_noisy_record(seed) for seed in range(4)]
    long = fit_physics(Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=tuple(TRUTH)), records).uncertainty.std["zeta"]
    assert long / short == pytest.approx(0.5, rel=0.2)  # 4x the samples


def test_describe_shows_the_standard_errors_and_intervals_of_the_fit_it_is_given():
    model = Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=tuple(TRUTH))
    fit = fit_physics(model, _noisy_record(0))
    text = model.describe(fit.uncertainty)
    assert "± std" in text and "95 % interval" in text
    assert f"{fit.uncertainty.std['zeta']:.3g}" in text
    assert "± std" not in model.describe()  # the module carries no fit's uncertainty


class ProductGain(AbstractPhysics):
    """$\\dot x = -x + a b u$: only the product ab is determined by any record."""

    state_names = ("x",)

    def __init__(self):
        super().__init__()
        register_parameters(self, [PhysicalParameter("a", 1.0, "-", Positive()),
                                   PhysicalParameter("b", 1.0, "-", Positive())], ("a", "b"))

    def derivative(self, t, x, u):
        return -x + self.a * self.b * u

    def output(self, x, u):
        return x


def test_a_combination_the_record_cannot_determine_is_named():
    record = _noisy_record(0)
    with pytest.warns(IdentifiabilityWarning, match=r"a [+-]1 % with b [+-]1 %.*richly"):
        fit = fit_physics(ProductGain(), Record(record.t, record.u, record.y), max_nfev=5)
    assert fit.uncertainty.collinearity > 1e3


def test_a_parameter_driven_to_the_limit_of_its_constraint_is_named_and_the_others_keep_their_errors():
    from torchpaml._fit.uncertainty import parameter_uncertainty

    generator = torch.Generator().manual_seed(0)
    jacobian = torch.randn(200, 3, generator=generator, dtype=torch.float64)
    jacobian[:, 2] = float("inf")  # a positive parameter at 0: its constraint's slope vanished
    residual = 0.1 * torch.randn(200, generator=generator, dtype=torch.float64)
    result = parameter_uncertainty(["a", "b", "k"], torch.tensor([1.0, 2.0, 0.0]), residual, jacobian, at_limit=["k"])
    assert result.std["k"] == float("inf") and result.interval["k"] == (0.0, float("inf"))
    assert 0 < result.std["a"] < 0.1 and 0 < result.std["b"] < 0.1
    assert result.warning.startswith("k ended at the limit of its constraint")
    alone = parameter_uncertainty(["k"], torch.tensor([0.0]), residual, jacobian[:, 2:], at_limit=["k"])
    assert alone.std == {"k": float("inf")} and alone.warning.startswith("k ended at the limit")
