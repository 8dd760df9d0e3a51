"""A tracking run written out: ``track.json`` and a figure of the innovation and the detector's statistic."""

from __future__ import annotations

import json
from pathlib import Path

from matplotlib.figure import Figure

from torchpaml._track.tracker import Tracking

__all__ = ["TRACK_SCHEMA_VERSION", "tracking_figure", "tracking_to_dict", "write_tracking"]

#: The version of ``track.json``'s layout (``docs/reference/outputs.md``).
TRACK_SCHEMA_VERSION = 2


def _numbers(values) -> list[float] | None:
    return None if values is None else [float(v) for v in values]


def tracking_to_dict(tracking: Tracking) -> dict:
    """``{schema_version, alarms: [{t, statistic, parameter}], innovation_rms: {output: rms}, seconds, threshold,
    samples, missing_samples, detector_from, x0, process_noise, false_alarms_per_hour}``
    (``docs/reference/outputs.md``)."""
    return {"schema_version": TRACK_SCHEMA_VERSION,
            "alarms": [{"t": a.t, "statistic": a.statistic, "parameter": a.parameter} for a in tracking.alarms],
            "innovation_rms": tracking.innovation_rms, "seconds": tracking.seconds, "threshold": tracking.threshold,
            "samples": len(tracking.t), "missing_samples": tracking.missing, "detector_from": tracking.detector_from,
            "x0": _numbers(tracking.x0), "process_noise": _numbers(tracking.process),
            "false_alarms_per_hour": tracking.false_alarms_per_hour}


def tracking_figure(tracking: Tracking) -> Figure:
    """The innovation of each output (top) and the windowed statistic with its threshold (bottom) against time, the
    alarms marked."""
    figure = Figure(figsize=(9, 5.5), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    for i, name in enumerate(tracking.outputs):
        top.plot(tracking.t, tracking.innovation[:, i], lw=0.6, label=name)  # gaps where NaN: missing, the start
    top.set_ylabel("innovation")
    top.legend(loc="upper right", fontsize=8)
    bottom.semilogy(tracking.t, tracking.statistic.clip(min=1e-12), lw=0.8, color="C0", label="statistic")
    bottom.axhline(tracking.threshold, color="C3", ls="--", lw=1, label="threshold")
    for alarm in tracking.alarms:
        for axis in (top, bottom):
            axis.axvline(alarm.t, color="C3", lw=0.8)
        bottom.annotate(alarm.parameter or "?", (alarm.t, tracking.threshold), xytext=(4, 6),
                        textcoords="offset points", fontsize=8, color="C3")
    bottom.set_xlabel("t (s)")
    bottom.set_ylabel("sum of normalised innovations²")
    bottom.legend(loc="upper left", fontsize=8)
    return figure


def write_tracking(tracking: Tracking, out: str | Path) -> Path:
    """Write ``track.json`` and ``track.png`` into the folder ``out``; returns the JSON's path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "track.json"
    path.write_text(json.dumps(tracking_to_dict(tracking), indent=2))
    tracking_figure(tracking).savefig(out / "track.png", dpi=110)
    return path
