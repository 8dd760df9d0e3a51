"""A candidate that does not act at its default start: the ranking probes it where it acts, or says that its score
cannot judge it; either way the answer does not hang on whether the fitted output reaches its level by a rounding.

The device: the demo's oscillator whose sensor clips at a level inside the signal's range (a user's effect,
``OutputClip``: $y \\to y - w\\,\\max(y - L, 0)$, a hard clip at $w = 1$). The candidate's default level lies above
every output, so there it moves no sample: inactive.
"""

import pytest
import torch

from torchpaml import (
    AbstractEffect,
    CoulombFriction,
    PhysicalParameter,
    QuadraticDamping,
    Real,
    Simulated,
    build_model,
    diagnose,
    register_parameters,
)
from torchpaml.report import ranking_table

pytestmark = pytest.mark.slow  # end-to-end diagnoses: the slow lane

LEVEL = 0.5  # the device's clip level, inside the output's range (its largest value about 1.1)


class OutputClip(AbstractEffect):
    """A user's sensor that clips above a level: $y \\to y - w\\,\\max(y - L, 0)$."""

    name, equation = "output_clip", "y -> y - w*max(y - level, 0)"

    def __init__(self, w: float = 0.0, level: float = 10.0, *, learn=("w", "level")):
        super().__init__()
        register_parameters(self, [PhysicalParameter("w", w, "-", Real(), "share of the excess clipped",
                                                     physical=(0.0, 1.0)),
                                   PhysicalParameter("level", level, "[y]", Real(), "clip level")], learn)

    def output_map(self, y):
        return y - self.w * (y - self.level).clamp(min=0)


class ClipProbedWhereItActs(OutputClip):
    """The same clip, probed at levels inside the measured output's range (its 90th and 75th percentiles)."""

    def starts(self, records):
        y = torch.cat([r.y.flatten() for r in records])
        return [{}, *({"level": float(torch.quantile(y, q))} for q in (0.9, 0.75))]


@pytest.fixture(scope="module")
def measured():
    device = build_model("oscillator", {"zeta": 0.2, "gain": 4.0}) + OutputClip(1.0, LEVEL)
    return [Simulated(device, signal, 1.0, [seed], 30.0, 0.05, noise=0.02).experiments()
            for signal, seed in (("pseudorandom", 0), ("multisine", 1))]


def physics():
    return build_model("oscillator").set_learnable("zeta", "omega0", "gain")


def test_a_candidate_inactive_at_its_default_start_is_found_where_it_acts(measured):
    train, validation = measured
    diagnosis = diagnose(physics(), [ClipProbedWhereItActs(), CoulombFriction(), QuadraticDamping()], train,
                         validation)
    assert diagnosis.ladder.added[0] == "output_clip", ranking_table(diagnosis.ranking)
    entry = diagnosis.ranking.entries[0]
    assert entry.acting > 0.05 and entry.refit_reason.startswith("refitted"), entry.refit_reason
    assert diagnosis.ladder.final.parameters["output_clip.level"] == pytest.approx(LEVEL, rel=0.05)
    assert diagnosis.ladder.final.nrmse_validation < 1.2 * 0.02  # at the noise floor


def test_a_candidate_that_acts_nowhere_is_not_judged_by_its_score_and_says_how_to_probe_it(measured):
    train, validation = measured
    diagnosis = diagnose(physics(), [OutputClip(), CoulombFriction()], train, validation)
    clip = next(e for e in diagnosis.ranking.entries if e.effect == "output_clip")
    assert clip.acting < 0.05 and clip.refit is None
    assert clip.refit_reason.startswith("not refitted: its first-order probe moves") and \
        "AbstractEffect.starts" in clip.refit_reason, clip.refit_reason
    assert "output_clip" not in diagnosis.ladder.added
