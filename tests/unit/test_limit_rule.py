"""The registry's one rule for what limits a benchmark's figure (``torchpaml.leaderboard.limit_of``): each label from
the numbers behind it, at both sides of each edge, and a sentence that states those numbers."""

import pytest

from torchpaml._diagnostics.analysis.adequacy import Adequacy
from torchpaml.leaderboard import LIMITS, MIN_REMOVED, LimitFigures, limit_of


def verdict(complete: bool, floor: float | None = 0.02) -> Adequacy:
    return Adequacy(inadequate=False, train_ratio=1.0, validation_ratio=1.0, message="", complete=complete,
                    noise_floor=floor)


@pytest.mark.parametrize("error, kind", [(1.19, "noise floor"), (1.21, "model class")])
def test_a_floor_measured_on_repeats_decides_at_twelve_tenths_whatever_the_diagnosis_says(error, kind):
    for complete in (True, False):
        label, evidence, sentence = limit_of(LimitFigures(error, "mV", verdict(complete), 0.021, floor=1.0))
        assert label == kind
        assert evidence["final_over_noise_floor"] == pytest.approx(error)
        assert sentence.startswith(f"the {kind}:") and f"{error:.3g} mV" in sentence and "1.0 mV" not in sentence


@pytest.mark.parametrize("complete, kind", [(True, "noise floor"), (False, "model class")])
def test_without_a_measured_floor_the_diagnosis_verdict_decides(complete, kind):
    label, evidence, sentence = limit_of(LimitFigures(0.3, "V", verdict(complete), 0.05))
    assert label == kind and "noise_floor" not in evidence
    assert evidence["validation_nrmse"] == 0.05 and evidence["diagnosis_noise_floor_nrmse"] == 0.02
    assert "validation mismatch 5 %, 2.50 times the noise floor it reads from the records, 2 %" in sentence


@pytest.mark.parametrize("removed, kind", [(MIN_REMOVED - 0.01, "noise floor"), (MIN_REMOVED + 0.01, "undetermined")])
def test_an_input_response_left_at_the_floor_makes_the_limit_undetermined(removed, kind):
    figures = LimitFigures(1.0, "m", verdict(True), 0.02, with_residual=1.0 - removed)
    label, evidence, sentence = limit_of(figures)
    assert label == kind and evidence["with_input_residual"] == pytest.approx(1.0 - removed)
    assert f"removes {100 * removed:.3g} %" in sentence


def test_above_the_floor_it_is_the_model_class_with_the_residuals_share_and_the_probes_place():
    figures = LimitFigures(2.0, "mm", verdict(False), 0.08, with_residual=1.5,
                           probe=("force", "constant_force", 0.25))
    label, evidence, sentence = limit_of(figures)
    assert label == "model class" and label in LIMITS
    assert evidence["probe_gain"] == 0.25 and evidence["with_input_residual"] == 1.5
    assert "removes 25 %" in sentence and "the probes point at the force (constant_force, a validation gain of 25 %)" \
        in sentence


def test_every_evidence_figure_is_a_finite_number_the_rule_read():
    _, evidence, _ = limit_of(LimitFigures(1.0, "V", verdict(False, floor=None), 0.1, floor=0.5, with_residual=0.9,
                                           probe=("sensor", "sensor_offset", 0.1)))
    assert set(evidence) == {"final", "validation_nrmse", "complete", "noise_floor", "final_over_noise_floor",
                             "with_input_residual", "probe_gain"}
