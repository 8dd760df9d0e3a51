"""The fleet's report: ``fleet.html``, a table of units ordered by severity, and the parameters' spread.

Severity: units that failed come first (they need attention), then units with missing effects, by
how much adding them lowered the validation mismatch, then the rest. The spread of every parameter
that at least three units have is drawn in ``fleet_parameters.png``, with the units that stand out
marked (:func:`~torchpaml._diagnostics.analysis.spread.parameter_spread`).
"""

from __future__ import annotations

import html
from pathlib import Path

from torchpaml._diagnostics.analysis.spread import REACH, ParameterSpread
from torchpaml._render.figures import fleet_figure

__all__ = ["severity_order", "write_fleet_report"]


def severity_order(units: list[dict]) -> list[dict]:
    """The rows of ``fleet.json`` ordered by severity (module docstring)."""
    def key(row: dict) -> tuple:
        if row["error"] is not None:
            return (0, 0.0, row["unit"])
        gain = row["nrmse_validation"]["baseline"] - row["nrmse_validation"]["final"]
        return (1 if row["found"] else 2, -gain, row["unit"])

    return sorted(units, key=key)


def _pct(value: float | None) -> str:
    return "—" if value is None else f"{100 * value:.2f}"


def write_fleet_report(fleet: dict, spreads: list[ParameterSpread], out: Path) -> Path:
    """Write ``fleet.html`` and ``fleet_parameters.png`` into ``out`` from the content of ``fleet.json`` and the
    parameters' spread across its healthy units (:func:`~torchpaml._diagnostics.analysis.spread.fleet_spread`)."""
    if spreads:
        fleet_figure(spreads).savefig(out / "fleet_parameters.png", dpi=100)
    rows = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(cell))}</td>" for cell in (
            row["unit"], "failed" if row["error"] else ("missing effects" if row["found"] else "as designed"),
            ", ".join(row["found"]) or "—", _pct(row["nrmse_validation"]["baseline"]),
            _pct(row["nrmse_validation"]["final"]), f"{row['seconds']:.1f}", row["error"] or "")) + "</tr>"
        for row in severity_order(fleet["units"]))
    outliers = "".join(f"<li><code>{html.escape(s.name)}</code>: {html.escape(', '.join(s.outliers))}</li>"
                       for s in spreads if s.outliers) or "<li>none</li>"
    figure = '<img src="fleet_parameters.png" alt="parameters across the fleet">' if spreads else ""
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>torchpaml fleet</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}} td,th{{border:1px solid #ccc;padding:3px 6px}}
table{{border-collapse:collapse}} img{{max-width:100%}}</style></head><body>
<h1>Fleet: {len(fleet['units'])} units</h1>
<p>{fleet['engine']} on {fleet['workers']} workers, {fleet['seconds']:.0f} s; each unit's diagnosis is in its
folder.</p>
<h2>Units, most severe first</h2>
<table><tr><th>unit</th><th>status</th><th>missing effects (in ladder order)</th><th>physics validation %</th>
<th>final validation %</th><th>seconds</th><th>error</th></tr>{rows}</table>
<h2>Parameters across the fleet</h2>
<p>A unit stands out when its estimate lies more than {REACH:g} combined standard deviations (its standard error
and the fleet's robust spread, 1.4826 MAD) from the fleet's median.</p>
<ul>{outliers}</ul>
{figure}
</body></html>
"""
    path = out / "fleet.html"
    path.write_text(page)
    return path
