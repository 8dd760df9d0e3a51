"""End to end: a shortened alpha = 4 paper pipeline and the reproduction command."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from torchpaml._paper import PaperSetup, reproduce_alpha

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_shortened_alpha4_pipeline_hybrid_beats_physics_and_zeta_holds():
    result = reproduce_alpha(4.0, [0, 1], PaperSetup(duration=40.0))
    assert result["zeta_hat"]["mean"] == pytest.approx(0.635, abs=0.01)
    for split in ("residual_id", "validation"):
        physics, hybrid = result[split]["physics"]["per_seed"], result[split]["hybrid"]["per_seed"]
        assert all(h < 0.5 * p for h, p in zip(hybrid, physics))
    assert all(abs(d) < 0.002 for d in result["delta_zeta"]["per_seed"])
    assert result["certificates"]["chebyshev"][-1]["zeroth_max"] < 1e-3


@pytest.mark.slow
def test_reproduce_script_writes_the_documented_json(tmp_path):
    done = subprocess.run(
        [sys.executable, str(ROOT / "experiments/paper/reproduce.py"), "--alpha", "4", "--seeds", "1", "--out",
         str(tmp_path)],
        check=True,
        capture_output=True,
        text=True,
    )
    assert "alpha 4: seed 1 of 1" in done.stderr  # its progress, one line per amplitude and seed
    report = json.loads((tmp_path / "results.json").read_text())
    entry = report["results"]["4"]
    for key in ("zeta_hat", "physical_id_mismatch", "delta_zeta"):
        assert set(entry[key]) >= {"mean", "per_seed"}
    for key in ("residual_id", "validation"):
        assert set(entry[key]) == {"physics", "hybrid"}
        assert set(entry[key]["hybrid"]) >= {"mean", "per_seed"}
    assert (tmp_path / "table.md").read_text().startswith("| quantity |")
