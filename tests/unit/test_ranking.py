"""rank_missing_effects: the first-order score's properties, and the errors it raises."""

import pytest
import torch

from torchpaml import RK4
from torchpaml import (
    AbstractEffect,
    CubicStiffness,
    DeadZone,
    InputSaturation,
    Oscillator,
    PhysicalParameter,
    Positive,
    QuadraticDamping,
    Record,
    fit_physics,
    pseudorandom,
    register_parameters,
    simulate,
    simulate_record,
    time_grid,
)
from torchpaml.analysis import rank_missing_effects
from torchpaml._data import Simulated
from torchpaml._diagnostics.ranking.probes import Secant, TangentLinear
from torchpaml._diagnostics.ranking.first_order import first_order
from torchpaml._diagnostics.ranking.refits import REFIT_CRITERION_STEP, refit_effect


@pytest.fixture(scope="module")
def duffing():
    """Noise-free training and validation records of a weak Duffing oscillator (20 s at 20 Hz)."""
    t = time_grid(20.0, 0.05)
    true = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CubicStiffness(0.5)
    made = []
    for seed in (0, 1):
        u = pseudorandom(t, 1.0, seed=seed)
        made.append(Record(t, u[0], simulate(true, t, u, solver=RK4())[0].detach(), f"seed{seed}"))
    return made


def fitted(record):
    base = Oscillator(zeta=0.3, omega0=2.0, gain=4.0, learn=("zeta", "omega0", "gain"))
    fit = fit_physics(base, record)
    scale = float(record.y.norm())
    return base, fit, simulate_record(base, record)[0, :, 0] / scale


@pytest.mark.parametrize("effect, order, one_sided", [
    (CubicStiffness(), 1, False), (QuadraticDamping(), 1, False), (InputSaturation(), 2, True), (DeadZone(), 1, True),
])
def test_order_and_probe_invariance(duffing, effect, order, one_sided):
    """The detected order, and a score that does not depend on the probe strength (1e-4 vs 1e-3) to 1e-3."""
    base, fit, reference = fitted(duffing[0])
    name = f"{effect.name}.{effect.strength}"
    scores = []
    for probe in (1e-4, 1e-3):
        score, found, *_ = first_order(base + effect, name, fit, float(duffing[0].y.norm()), probe, reference,
                                       Secant(base, duffing[:1], fit.initial_states,
                                              fit.solver))
        assert found == order
        scores.append(score)
    assert scores[0] == pytest.approx(scores[1], abs=1e-3)
    assert 0.0 <= scores[0] <= 1.0


def test_the_true_effect_explains_almost_all_of_a_small_residual(duffing):
    """Noise-free data and a weak effect: first order is nearly exact, so the score is near 1 and k1 near k3."""
    base, fit, reference = fitted(duffing[0])
    score, _, strength, _, _ = first_order(base + CubicStiffness(), "cubic_stiffness.k3", fit,
                                            float(duffing[0].y.norm()),
                                         1e-4, reference, Secant(base, duffing[:1], fit.initial_states,
                                              fit.solver))
    assert score > 0.97
    assert strength == pytest.approx(0.5, rel=0.15)


def strong_cubic_first_order():
    """The case of benchmarks/bench_ranking.py, a strong cubic term (k3 = 2) and 2 % noise: the linear oscillator,
    its record, its fit, and the first-order strength and move of cubic stiffness."""
    true = Oscillator(zeta=0.2, omega0=2.0, gain=4.0, learn=()) + CubicStiffness(2.0)
    record = Simulated(true, "pseudorandom", 1.5, [0], 30.0, 0.05, noise=0.02).experiments()[0]
    base = Oscillator(zeta=0.5, omega0=1.5, gain=1.0, learn=("zeta", "omega0", "gain"))
    fit = fit_physics(base, record)
    engine = TangentLinear.of(base, [record], fit.initial_states)
    _, _, strength, move, _ = first_order(base + CubicStiffness(), "cubic_stiffness.k3", fit, float(record.y.norm()),
                                        1e-4, engine.outputs(base) / float(record.y.norm()), engine)
    return base, record, fit, strength, move


def test_the_first_order_step_starts_the_refit_nearer():
    """The refit from the first-order Gauss-Newton step (strength and the physics' own parameters) reaches the
    optimum of a refit from the strength alone (to 1e-6, both at the ranking's tolerance), in fewer simulations.
    The case of benchmarks/bench_ranking.py: a strong cubic term (k3 = 2), 2 % noise."""
    base, record, fit, strength, move = strong_cubic_first_order()
    name, ftol = "cubic_stiffness.k3", REFIT_CRITERION_STEP / len(record.y)
    stepped = refit_effect(base + CubicStiffness(), name, strength, [record], 40, "rest", fit, move, ftol)
    alone = refit_effect(base + CubicStiffness(), name, strength, [record], 40, "rest", ftol=ftol)
    assert stepped.evaluations < alone.evaluations
    for key, value in alone.parameters.items():
        assert stepped.parameters[key] == pytest.approx(value, rel=1e-6)


def test_a_refit_that_ends_worse_than_the_baseline_is_rescued_from_a_shortened_move():
    """A first-order step four times too long (strength and unknowns) fails the move's check; the fit from the
    unmoved unknowns, cut to one evaluation, ends worse than the baseline (a poor optimum's stand-in); then half the
    move starts a fit that beats the baseline, and that fit is returned, the model left at it."""
    base, record, fit, strength, move = strong_cubic_first_order()
    name, ftol = "cubic_stiffness.k3", REFIT_CRITERION_STEP / len(record.y)
    alone = refit_effect(base + CubicStiffness(), name, 4 * strength, [record], 1, "rest", ftol=ftol)
    assert alone.mismatch > fit.mismatch  # the premise: without a move the cut fit ends worse than the baseline
    extended = base + CubicStiffness()
    rescued = refit_effect(extended, name, 4 * strength, [record], 1, "rest", fit, 4 * move, ftol)
    assert rescued.mismatch < fit.mismatch
    assert extended.physical_parameters()["cubic_stiffness.k3"] == pytest.approx(rescued.parameters[name], rel=1e-12)


def test_no_candidates_give_the_fitted_baseline_alone(duffing):
    ranking = rank_missing_effects(Oscillator(zeta=0.3, learn=("zeta", "omega0", "gain")), [], *duffing)
    assert ranking.entries == [] and ranking.recommended is None
    assert ranking.baseline.nrmse_train < 0.2  # fitted: the weak cubic term is what is left


def test_warm_started_secant_outputs_equal_cold_simulations(duffing):
    """Newton from the base's trajectory converges to the same RK4 solution: equal to 1e-10 (its tolerance)."""
    record = duffing[0]
    base, fit, _ = fitted(record)
    extended = (base + CubicStiffness()).assign(**{"cubic_stiffness.k3": 0.3})
    warm = Secant(base, [record], fit.initial_states, fit.solver).outputs(extended)
    cold = simulate_record(extended, record, solver=RK4(substeps=1)).flatten()
    assert float((warm - cold).abs().max() / cold.abs().max()) < 1e-10


class Offset(AbstractEffect):
    """Not off at zero strength: a constant force of 1 plus k."""

    name, equation = "offset", "+ 1 + k"

    def __init__(self, k: float = 0.0):
        super().__init__()
        register_parameters(self, [PhysicalParameter("k", k)], ("k",))

    def force(self, physics, x, v, u):
        return (1.0 + self.k) * torch.ones_like(x)


class PositiveStrength(AbstractEffect):
    name, equation = "positive", "- c*x"

    def __init__(self, c: float = 1.0):
        super().__init__()
        register_parameters(self, [PhysicalParameter("c", c, constraint=Positive())], ("c",))

    def force(self, physics, x, v, u):
        return -self.c * x


@pytest.mark.parametrize("physics, candidates, error, message", [
    (Oscillator(learn=("zeta",)), [Offset()], ValueError, "changes the model at zero strength"),
    (Oscillator(learn=("zeta",)), [PositiveStrength()], ValueError, "cannot be 0"),
    (Oscillator(learn=("zeta",)), [CubicStiffness(), CubicStiffness()], ValueError, "distinct names"),
    (Oscillator(learn=("zeta",)) + CubicStiffness(), [CubicStiffness()], ValueError, "already in"),
])
def test_bad_candidates_are_errors_that_name_the_fix(duffing, physics, candidates, error, message):
    with pytest.raises(error, match=message):
        rank_missing_effects(physics, candidates, duffing[0], duffing[1])


@pytest.mark.parametrize("effect", [CubicStiffness(), QuadraticDamping(), InputSaturation(), DeadZone()])
def test_tangent_linear_outputs_equal_the_simulated_change(duffing, effect):
    # For a linear base, the first-order change of the output in the strength is the base's linear response to
    # the effect's force along the baseline. Against RK4 simulations of base + effect (differenced against the
    # same model at strength 0, so RK4's own error cancels) it differs by O(delta) and by the first-order hold
    # of the force between samples, O((h omega0)^2) = 1e-2 here: held to 5 %.
    from torchpaml._diagnostics.ranking.probes import TangentLinear

    record = duffing[0]
    base, _, _ = fitted(record)
    extended = base + effect
    name = f"{effect.name}.{effect.strength}"
    x0 = torch.tensor([0.3, -0.2], dtype=torch.float64)  # not at rest: the baseline trajectory starts from x0
    tangent = TangentLinear.of(base, [record], [x0])
    extended.assign(**{name: 0.0})
    simulated_off, linear_off = simulate_record(extended, record, x0).flatten(), tangent.outputs(extended)
    extended.assign(**{name: 1e-3})
    simulated = simulate_record(extended, record, x0).flatten() - simulated_off
    linear = tangent.outputs(extended) - linear_off
    assert float((simulated - linear).norm() / simulated.norm()) < 0.05


def test_candidates_that_do_not_apply_are_skipped_and_listed(duffing):
    # a user's second-order physics without omega0: pendulum_restoring (scaled by omega0) cannot act on it
    from torchpaml._physics import PendulumRestoring, SecondOrderPhysics

    class Spring(SecondOrderPhysics):
        def __init__(self, c=0.8, k=4.0, g=4.0, *, learn=("c", "k", "g")):
            super().__init__()
            register_parameters(self, [PhysicalParameter("c", c, "1/s", Positive()),
                                       PhysicalParameter("k", k, "1/s^2", Positive()),
                                       PhysicalParameter("g", g, "-", Positive())], learn)

        def acceleration(self, t, x, v, u):
            return self.g * u - self.c * v - self.k * x

    with pytest.raises(TypeError, match="omega0, and Spring has none"):
        Spring() + PendulumRestoring()
    ranking = rank_missing_effects(Spring(), [CubicStiffness(), PendulumRestoring()], *duffing, shortlist=1)
    assert list(ranking.skipped) == ["pendulum_restoring"] and "omega0" in ranking.skipped["pendulum_restoring"]
    assert [e.effect for e in ranking.entries] == ["cubic_stiffness"]


def test_a_numerically_null_direction_of_the_physics_does_not_move_the_score():
    """A column that repeats another up to rounding (a parameter at its constraint's limit, an exact degeneracy) adds a
    direction the least squares would keep or drop by its last digits: the projection leaves it out."""
    from torchpaml._diagnostics.ranking.first_order import NULL_DIRECTION, beyond_physics

    generator = torch.Generator().manual_seed(0)
    J = torch.randn(500, 3, generator=generator, dtype=torch.float64)
    d = torch.randn(500, generator=generator, dtype=torch.float64)
    noise = torch.randn(500, generator=generator, dtype=torch.float64)
    degenerate = torch.cat([J, (J[:, 0] + 1e-14 * noise)[:, None]], dim=1)
    projected, energy = beyond_physics(d, J)
    again, again_energy = beyond_physics(d, degenerate)
    assert again_energy == pytest.approx(energy, rel=1e-9) and torch.allclose(again, projected, atol=1e-9)
    full = d - degenerate @ torch.linalg.lstsq(degenerate, d[:, None], driver="gelsd", rcond=1e-16).solution[:, 0]
    assert float(full @ full) < 0.999 * energy  # the full least squares spans the rounding's direction too
    assert NULL_DIRECTION > 1e-14


def test_a_column_of_rounding_does_not_move_the_score():
    """A parameter that does not move the output (its Jacobian column the rounding of a central difference: 0 on one
    copy of the records, 1e-12 on the same records perturbed) gives the same projection either way: the column is
    left out before the scaling to unit norm, which would otherwise make its noise a direction (the cascaded tanks'
    seed-4 records: first-order scores 20 to 60 % apart, another ladder)."""
    from torchpaml._diagnostics.ranking.first_order import NULL_COLUMN, beyond_physics

    generator = torch.Generator().manual_seed(0)
    J = torch.randn(500, 3, generator=generator, dtype=torch.float64)
    d = torch.randn(500, generator=generator, dtype=torch.float64)
    noise = torch.randn(500, generator=generator, dtype=torch.float64)
    projected, energy = beyond_physics(d, torch.cat([J, torch.zeros(500, 1, dtype=torch.float64)], dim=1))
    again, again_energy = beyond_physics(d, torch.cat([J, 1e-12 * noise[:, None]], dim=1))
    assert again_energy == pytest.approx(energy, rel=1e-12) and torch.allclose(again, projected, atol=1e-12)
    weak, weak_energy = beyond_physics(d, torch.cat([J, 1e-6 * noise[:, None]], dim=1))  # small, but it moves y
    assert weak_energy < 0.999 * energy
    assert 1e-12 < NULL_COLUMN < 1e-6
