"""The probes' places and their bookkeeping: every library effect has one place, where in time an error sits, the
ranking of the places' gains (ties by the places' order), and a place naming no library effect is refused."""

from types import SimpleNamespace

import pytest
import torch

from torchpaml import EFFECTS, ConfigurationError, Prober, Record
from torchpaml.analysis import PLACES, Place, ProbeResult, error_in_time
from torchpaml._diagnostics.mismatch.result import DISCOVERED, GAIN_TIE, MismatchProbes, ranked


def test_every_library_effect_is_probed_at_exactly_one_place():
    names = [name for place in PLACES for name in place.effects]
    assert sorted(names) == sorted(EFFECTS)


def test_a_place_that_names_an_effect_outside_the_library_is_refused():
    with pytest.raises(ConfigurationError, match="outside the library: \\['sensor_drift'\\]"):
        Prober(places=(Place("sensor", "a drift", ("sensor_drift",)),))


def _record(error):
    t = torch.arange(len(error), dtype=torch.float64) * 0.1
    return Record(t, torch.zeros(len(t), 1, dtype=torch.float64), error[:, None]), torch.zeros(len(t), 1)


@pytest.mark.parametrize("shape, share, growth, words", [
    (lambda n: torch.ones(n), 0.1, 1.0, "spread evenly"),
    (lambda n: torch.exp(-torch.arange(n) / 20.0), 0.99, 0.0, "concentrated at the start"),
    # a ramp: the RMS of t over [0.55, 1] against [0.1, 0.55]
    (lambda n: torch.arange(n) / n, 0.0, ((1 - 0.55**3) / (0.55**3 - 0.1**3)) ** 0.5, "grows (drift)"),
])
def test_where_in_time_an_error_sits(shape, share, growth, words):
    record, output = _record(shape(1000).double())
    found = error_in_time([record], [output.double()])
    assert found.start_share == pytest.approx(share, abs=0.01)
    assert found.growth == pytest.approx(growth, abs=0.05)
    assert words in found.describe()


def test_gains_within_the_tie_rank_in_the_places_order_and_the_best_needs_the_minimum_gain():
    rows = [ProbeResult("force", "", "f", 0.5, 0.30), ProbeResult("sensor dynamics", "", "s", 0.5, 0.30 + GAIN_TIE / 2),
            ProbeResult("actuator dynamics", "", "a", 0.5, 0.30 - GAIN_TIE / 2), ProbeResult("input map", "", note="x"),
            ProbeResult("extra mode", "", "e", 0.7, 0.02)]
    order = [place.name for place in PLACES]
    assert [r.place for r in ranked(rows, order)] == ["actuator dynamics", "sensor dynamics", "force", "extra mode",
                                                      "input map"]
    probes = MismatchProbes("m", 0.7, ranked(rows, order))
    assert probes.best.place == "actuator dynamics" and "the actuator dynamics (a: validation 70.00 %" in probes.describe()
    low = MismatchProbes("m", 0.7, [ProbeResult("extra mode", "", "e", 0.7, 0.02)])
    assert low.best is None and "at none of these places" in low.describe()


def test_the_discoverys_closed_form_joins_the_force_place_after_the_probes():
    """A diagnosis probes before it discovers: the discovery's form then takes the force's row where it gains more
    than the row's library effect, and the table is ranked again; a discovery that found no form changes nothing."""
    rows = [ProbeResult("sensor dynamics", "a lag", "sensor_lag", 0.080, 0.20),
            ProbeResult("force", "a force", "quadratic_damping", 0.090, 0.10)]
    probes = MismatchProbes("m", 0.100, rows=rows, places=("sensor dynamics", "force"))
    found = SimpleNamespace(discovered=SimpleNamespace(nrmse_validation=0.050), text="- 0.6*v**3")
    joined = probes.with_discovery(found)
    assert [r.place for r in joined.rows] == ["force", "sensor dynamics"]
    assert joined.best.fitted == "- 0.6*v**3" and joined.best.gain == pytest.approx(0.5)
    assert joined.best.note == DISCOVERED and probes.rows[1].fitted == "quadratic_damping"  # the original kept
    worse = SimpleNamespace(discovered=SimpleNamespace(nrmse_validation=0.095), text="- 0.1*v**3")
    assert probes.with_discovery(worse).rows[1].fitted == "quadratic_damping"
    assert probes.with_discovery(SimpleNamespace(discovered=None, text="")) is probes
    assert MismatchProbes("m", 0.1, reason="complete").with_discovery(found).rows == []
