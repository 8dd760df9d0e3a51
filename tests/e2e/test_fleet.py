"""``torchpaml fleet`` on a local Ray: a generated fleet, a broken unit, resuming, --force and Ctrl-C.

The fleet (``experiments/fleet/make_fleet.py``): units of the demo's oscillator with manufacturing
spread; three have developed an effect and one has an outlying natural frequency. Skipped without Ray
(``pip install 'torchpaml[fleet]'``).
"""

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import pytest

from experiment_modules import load
from torchpaml.cli import main

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane

OUTPUTS_PAGE = os.path.join(os.path.dirname(__file__), "..", "..", "docs", "reference", "outputs.md")

pytest.importorskip("ray", reason="torchpaml fleet needs the extra: pip install 'torchpaml[fleet]'")
make_fleet = load("fleet/make_fleet.py")


def fleet(monkeypatch, units, out, *extra):
    monkeypatch.setattr(sys, "argv", ["torchpaml"])
    main(["fleet", "--units", str(units), "--physics", "oscillator", "--out", str(out), "--quiet", *extra])
    return json.loads((out / "fleet.json").read_text())


@pytest.fixture(scope="module")
def units(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet") / "units"
    truth = make_fleet.make_fleet(folder, units=9)
    broken = folder / "unit_broken"
    shutil.copytree(folder / "unit00", broken)
    lines = (broken / "train.csv").read_text().splitlines()
    lines[5] = ",".join(lines[5].split(",")[:2] + ["nan"])  # one NaN in y
    (broken / "train.csv").write_text("\n".join(lines) + "\n")
    return folder, truth


def test_every_unit_is_diagnosed_a_broken_one_fails_alone_and_a_rerun_skips_the_finished(units, tmp_path,
                                                                                         monkeypatch):
    folder = tmp_path / "units"  # the three developed effects, the outlier, two plain units and the broken one
    truth = {unit: row for unit, row in units[1].items() if unit not in ("unit01", "unit03", "unit04")}
    for unit in (*truth, "unit_broken"):
        shutil.copytree(units[0] / unit, folder / unit)
    out = tmp_path / "out"
    result = fleet(monkeypatch, folder, out)
    assert result["engine"] == "ray" and result["workers"] == 2 and result["schema_version"] == 1
    rows = {row["unit"]: row for row in result["units"]}
    assert sorted(rows) == sorted([*truth, "unit_broken"])
    assert "DataError" in rows["unit_broken"]["error"] and "NaN" in rows["unit_broken"]["error"]
    for unit, expected in truth.items():
        row = rows[unit]
        assert row["error"] is None, row["error"]
        assert row["found"] == ([expected["effect"]] if expected["effect"] else []), unit
        assert row["nrmse_validation"]["final"] < 1.5 * 0.02  # at the 2 % noise floor
        assert row["parameters"]["omega0"] == pytest.approx(expected["parameters"]["omega0"], rel=0.02)
        assert row["seconds"] > 0 and (out / unit / "diagnosis.json").is_file()
    assert not list(out.glob(".*.partial"))
    page = (out / "fleet.html").read_text()
    assert page.index("unit_broken") < page.index("unit02") < page.index("unit00")  # failed, changed, as designed
    assert "<li><code>omega0</code>: unit08</li>" in page and (out / "fleet_parameters.png").stat().st_size > 1000
    with open(OUTPUTS_PAGE) as page_file:
        spans = re.findall(r"`([^`]+)`", page_file.read())
    documented = {word for span in spans for word in re.findall(r"\w+", span)}
    fields = set(result) | set(rows["unit00"]) | set(rows["unit00"]["nrmse_validation"])
    assert sorted(fields - documented) == []  # every field of fleet.json is on the reference page

    stamps = {unit: (out / unit / "unit.json").stat().st_mtime_ns for unit in truth}
    again = fleet(monkeypatch, folder, out)
    assert again["skipped"] == sorted(truth)  # every finished unit; the failed one is run again
    assert {unit: (out / unit / "unit.json").stat().st_mtime_ns for unit in truth} == stamps
    assert [row for row in again["units"] if row["unit"] != "unit_broken"] == \
        [row for row in result["units"] if row["unit"] != "unit_broken"]


def test_force_diagnoses_a_finished_unit_again(units, tmp_path, monkeypatch):
    folder, _ = units
    one = tmp_path / "one"
    shutil.copytree(folder / "unit00", one / "unit00")  # as designed: its diagnosis stops at the first rung
    first = fleet(monkeypatch, one, tmp_path / "out")
    stamp = (tmp_path / "out" / "unit00" / "unit.json").stat().st_mtime_ns
    forced = fleet(monkeypatch, one, tmp_path / "out", "--force")
    assert forced["skipped"] == [] and (tmp_path / "out" / "unit00" / "unit.json").stat().st_mtime_ns > stamp
    assert forced["units"][0] == {**first["units"][0], "seconds": forced["units"][0]["seconds"]}


def test_ctrl_c_stops_the_workers_and_keeps_the_finished_units(units, tmp_path):
    folder = tmp_path / "units"  # three units on two workers: the third is still running when the first is done
    for unit in ("unit00", "unit01", "unit03"):
        shutil.copytree(units[0] / unit, folder / unit)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "torchpaml", "fleet", "--units", str(folder), "--physics", "oscillator",
               "--out", str(out), "--quiet"]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list(out.glob("unit*/unit.json")) and time.monotonic() < deadline:
        time.sleep(0.2)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stderr
    assert "interrupted; the finished units are kept" in stderr
    done = sorted(path.parent.name for path in out.glob("unit*/unit.json"))
    assert 1 <= len(done) < 3
    for unit in done:  # each finished unit is whole
        assert (out / unit / "diagnosis.json").is_file() and (out / unit / "report.html").is_file()
    assert not (out / "fleet.json").exists()
    resumed = subprocess.run(command, capture_output=True, text=True, env={**os.environ})
    assert resumed.returncode == 0, resumed.stderr
    result = json.loads((out / "fleet.json").read_text())
    assert set(done) <= set(result["skipped"])
    assert len(result["units"]) == 3
