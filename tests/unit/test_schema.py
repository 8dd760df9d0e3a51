"""The JSON contracts carry no infinite number: an undetermined standard error is written as null."""

import json
import math

from torchpaml import Oscillator
from torchpaml._diagnostics import Ladder, ModelScore
from torchpaml._render.schema import ladder_to_dicts


def test_an_undetermined_standard_error_is_written_as_null():
    score = ModelScore("Oscillator", "Oscillator", {"zeta": 0.2, "omega0": 2.0}, 0.02, 0.02, -100.0, Oscillator(),
                       uncertainty={"zeta": 0.001, "omega0": math.inf})
    (rung,) = ladder_to_dicts(Ladder([score], [], []))
    assert rung["uncertainty"] == {"zeta": 0.001, "omega0": None}
    assert "Infinity" not in json.dumps(rung)

