"""Records that do not start at rest: the initial state estimated with the parameters, and on its own."""

import pytest
import torch

from torchpaml import Estimate, CubicStiffness, Record, Rest, fit_physics, Oscillator, pseudorandom, time_grid

X0 = torch.tensor([[0.8, -1.5]], dtype=torch.float64)


def _record(model, seed=0) -> Record:
    t = time_grid(10.0, 0.02)
    u = pseudorandom(t, 1.0, seed=seed)
    with torch.no_grad():
        y = model(t, u, X0)
    return Record(t, u[0], y[0])


@pytest.mark.parametrize("nonlinear", [False, True], ids=["exact path", "rk4 engine"])
def test_the_initial_state_is_estimated_with_the_parameters(nonlinear):
    truth = Oscillator(0.2, 2.0, 4.0) + CubicStiffness(1.5) if nonlinear else Oscillator(0.2, 2.0, 4.0)
    record = _record(truth)
    model = Oscillator(0.4, 1.8, 3.0, learn=("zeta", "omega0", "gain"))
    model = model + CubicStiffness(1.0) if nonlinear else model
    fit = fit_physics(model, record, initial_state=Estimate())
    assert fit.initial_states[0] == pytest.approx(X0[0], abs=1e-6)
    assert fit.parameters["zeta"] == pytest.approx(0.2, abs=1e-6)
    assert fit.mismatch < 1e-7
    assert set(fit.uncertainty.std) >= {"x0[record].position", "x0[record].velocity"}


def test_from_rest_the_same_record_leaves_a_transient_error():
    record = _record(Oscillator(0.2, 2.0, 4.0))
    fit = fit_physics(Oscillator(0.4, 1.8, 3.0, learn=("zeta", "omega0", "gain")), record)
    assert fit.mismatch > 1e-3
    assert fit.initial_states[0].abs().sum() == 0


def test_only_the_initial_state_when_no_parameter_is_learnable():
    truth = Oscillator(0.2, 2.0, 4.0, learn=())
    fit = fit_physics(truth, _record(truth), initial_state=Estimate())
    assert fit.parameters == {}
    assert fit.initial_states[0] == pytest.approx(X0[0], abs=1e-8)


def test_an_unknown_initial_state_option_is_refused():
    with pytest.raises(ValueError, match="'rest' or 'estimate'"):
        fit_physics(Oscillator(), _record(Oscillator()), initial_state="zero")


def test_starting_guesses_of_the_initial_states_go_to_the_first_rung_and_the_ladder_climbs_on():
    """``diagnose(..., start_states=)`` with an effect added: the guesses start the first rung's fit only (each next
    rung starts from its refit's states), and the ladder does not stop on them."""
    from torchpaml import diagnose

    truth = Oscillator(0.2, 2.0, 4.0, learn=()) + CubicStiffness(1.5)
    train, validation = _record(truth), _record(truth, seed=1)
    diagnosis = diagnose(Oscillator(0.4, 1.8, 3.0, learn=("zeta", "omega0", "gain")), [CubicStiffness()], train,
                         validation, initial_state=Estimate(), start_states=[X0[0]], prober=None)
    assert diagnosis.ladder.added == ["cubic_stiffness"]
    assert diagnosis.ladder.final.train_states[0] == pytest.approx(X0[0], abs=1e-5)


@pytest.mark.parametrize("start, gains", [(X0, True), (None, False)], ids=["away from rest", "at rest"])
def test_the_initial_state_probe_measures_its_gain_on_samples_its_fit_did_not_see(start, gains):
    """The probe estimates each validation record's state on its first 10 % and scores the rest. A record that
    starts away from rest gains there (its transient is the error); one that starts at rest gains nothing."""
    from torchpaml import SelectionRule
    from torchpaml._diagnostics.mismatch.prober import held_out_gain
    from torchpaml._diagnostics.ranking.scoring import score_model
    from torchpaml._fit.initial_state import START_WINDOW

    truth = Oscillator(0.2, 2.0, 4.0, learn=())
    t = time_grid(10.0, 0.02)
    u = pseudorandom(t, 1.0, seed=1)
    with torch.no_grad():
        clean = truth(t, u, start)[0]
    noisy = clean + 0.02 * clean.std() * torch.randn(clean.shape, generator=torch.Generator().manual_seed(3),
                                                    dtype=torch.float64)
    validation = Record(t, u[0], noisy, "validation")
    model = Oscillator(0.2, 2.0, 4.0, learn=("zeta", "omega0", "gain"))
    train = _record(Oscillator(0.2, 2.0, 4.0))
    fit = fit_physics(model, train, initial_state=Estimate())
    score = score_model(model, fit, [validation], SelectionRule())
    estimated = score_model(model, fit, [validation], SelectionRule(), Estimate())
    held_out, gain = estimated.nrmse_validation, held_out_gain(score, estimated, [validation])
    assert START_WINDOW == 0.1
    if gains:
        assert gain > 0.5 and held_out < 0.05  # the transient was the error
    else:  # no transient: no gain on the unseen samples (measured -1.2 %: the state fitted to the window's noise)
        assert gain < 0.005


def test_a_validation_record_is_scored_after_the_window_its_start_was_estimated_on():
    """``Estimate()`` estimates each validation record's state on its start window (10 %, at least 20 samples) and
    scores the samples after it: a model wrong only inside that window scores as the truth, one wrong after it
    does not, and the estimate sees only the window."""
    from torchpaml import SelectionRule
    from torchpaml._diagnostics.ranking.scoring import score_model, scored_mismatch
    from torchpaml._fit.initial_state import start_window

    truth = Oscillator(0.2, 2.0, 4.0, learn=())
    validation = _record(truth, seed=1)
    samples = len(validation.t)
    assert start_window(samples) == samples // 10 and start_window(100) == 20 and start_window(40) == 20
    fit = fit_physics(truth, _record(truth), initial_state=Estimate())
    score = score_model(truth, fit, [validation], SelectionRule(), Estimate())
    assert score.validation_states[0] == pytest.approx(X0[0], abs=1e-6)  # the window holds the start
    assert score.nrmse_validation < 1e-7 and score.samples == samples - start_window(samples)
    first = start_window(samples)
    wrong_inside, wrong_after = score.validation_outputs[0].clone(), score.validation_outputs[0].clone()
    wrong_inside[:first] += 1.0
    wrong_after[first:] += 1.0
    assert scored_mismatch([validation], [wrong_inside], Estimate()) < 1e-7
    assert scored_mismatch([validation], [wrong_after], Estimate()) > 0.1
    assert scored_mismatch([validation], [wrong_inside], Rest()) > 0.1  # from rest every sample is scored


@pytest.mark.parametrize("samples", [39, 21])
def test_a_validation_record_too_short_for_a_window_and_as_many_scored_samples_is_refused_before_any_fit(samples):
    """Under ``Estimate()`` a validation record of fewer than 2 x MIN_START_SAMPLES samples would be scored on the
    few samples after its window: refused by name, in ``diagnose`` before any fit; from rest it is scored whole."""
    from torchpaml import DataError, diagnose
    from torchpaml._fit.initial_state import MIN_START_SAMPLES, start_window

    assert samples < 2 * MIN_START_SAMPLES
    truth = Oscillator(0.2, 2.0, 4.0, learn=())
    short = _record(truth, seed=1).window(0, samples, name="short")
    with pytest.raises(DataError, match=rf"record 'short' has {samples} samples.*at least {2 * MIN_START_SAMPLES}"):
        Estimate().scored_from(short)
    with pytest.raises(DataError, match=f"has {samples} samples"):
        start_window(samples)
    assert Rest().scored_from(short) == 0
    fits = []
    monkey = pytest.MonkeyPatch()
    monkey.setattr("torchpaml._diagnostics.diagnosis.model_ladder", lambda *a, **k: fits.append(1))
    with pytest.raises(DataError, match=f"record 'short' has {samples} samples"):
        diagnose(Oscillator(), [], [_record(truth)], [short], initial_state=Estimate())
    monkey.undo()
    assert not fits
