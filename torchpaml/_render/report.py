"""Writing a :class:`~torchpaml.Diagnosis` out: JSON, PNG figures, an HTML report and TensorBoard logs.

Layout of ``out``::

    diagnosis.json      diagnosis_to_dict(diagnosis) (mismatches as fractions)
    discovery.json      discovery_to_dict(diagnosis.discovery), when the discovery ran
    discovered_effect.yaml   the discovered force as a config block (``candidates:`` of a --config), when one was found
    figures/NAME.png    compare, residual_analysis, error_by_amplitude, ranking, ladder (and discovery)
    report.html         the story in one page, showing the figures (and the table "where the mismatch points")
    model.pt            the final model (torchpaml.load_model), where a model file can keep it
    hybrid.pt           the final rung with the Chebyshev residual on top, where the alarm recommends the hybrid
    tensorboard/        scalars ladder/nrmse_validation and ladder/nrmse_train (one point per rung),
                        ranking/score/EFFECT, discovery/nrmse_validation/{physics, library_best, neural,
                        discovered}, probes/gain/PLACE, the figures under diagnose/, the verdict, the final equation and the
                        discovered expression as text
"""

from __future__ import annotations

import html
import json
import warnings
from pathlib import Path

import yaml
from torch.utils.tensorboard import SummaryWriter

from torchpaml._diagnostics.diagnosis import Diagnosis
from torchpaml._diagnostics.results import ModelScore
from torchpaml._errors import ConfigurationError
from torchpaml._model.file import save_model
from torchpaml._render.figures import diagnosis_figures
from torchpaml._render.schema import diagnosis_to_dict

__all__ = ["write_report"]


def write_report(diagnosis: Diagnosis, out: str | Path) -> Path:
    """Write every output into the folder ``out`` (module docstring); returns the path of ``diagnosis.json``."""
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    content = diagnosis_to_dict(diagnosis)
    figures = diagnosis_figures(diagnosis)
    for name, fig in figures.items():
        fig.savefig(out / "figures" / f"{name}.png", dpi=110)
    (out / "report.html").write_text(_html(diagnosis, content, list(figures)))
    _tensorboard(diagnosis, content, figures, out / "tensorboard")
    path = out / "diagnosis.json"
    path.write_text(json.dumps(content, indent=2))
    _save_models(diagnosis, out)
    discovery = diagnosis.discovery
    if discovery is not None:
        (out / "discovery.json").write_text(json.dumps(content["discovery"], indent=2))
        if discovery.effect is not None:
            (out / "discovered_effect.yaml").write_text(
                f"# {discovery.text}\n# add to `candidates:` of a `torchpaml diagnose --config` file\n"
                + yaml.safe_dump([discovery.effect.to_config()], sort_keys=False))
    return path


def _save_models(diagnosis: Diagnosis, out: Path) -> None:
    """``model.pt`` and, where the alarm recommends the hybrid, ``hybrid.pt`` (a ``hybrid.pt`` of an earlier run is
    removed where it does not); a model a file cannot keep is reported in a warning and skipped."""
    for name, model in (("model.pt", diagnosis.model), ("hybrid.pt", diagnosis.hybrid)):
        (out / name).unlink(missing_ok=True)
        if model is None:
            continue
        try:
            save_model(model, out / name)
        except ConfigurationError as reason:
            warnings.warn(f"{name} not written: {reason}", stacklevel=3)


def _tensorboard(diagnosis: Diagnosis, content: dict, figures: dict, folder: Path) -> None:
    writer = SummaryWriter(str(folder))
    for step, rung in enumerate(diagnosis.ladder.steps):
        writer.add_scalar("ladder/nrmse_validation", rung.nrmse_validation, step)
        writer.add_scalar("ladder/nrmse_train", rung.nrmse_train, step)
    for channel in diagnosis.channels:  # each output's validation mismatch: the fitted physics (0), the final model (1)
        for step, value in enumerate((channel.physics, channel.final)):
            writer.add_scalar(f"channels/{channel.name}/nrmse_validation", value, step)
    for entry in diagnosis.ranking.entries:
        writer.add_scalar(f"ranking/score/{entry.effect}", entry.score, 0)
        if entry.refit is not None:
            writer.add_scalar(f"ranking/nrmse_validation/{entry.effect}", entry.refit.nrmse_validation, 0)
    for name, fig in figures.items():
        writer.add_figure(f"diagnose/{name}", fig, 0)
    if diagnosis.discovery is not None:
        for key, value in content["discovery"]["nrmse_validation"].items():
            if value is not None:
                writer.add_scalar(f"discovery/nrmse_validation/{key}", value, 0)
        writer.add_text("discovery/expression", diagnosis.discovery.text, 0)
    for row in diagnosis.probes.rows if diagnosis.probes is not None else []:
        if row.gain is not None:
            writer.add_scalar(f"probes/gain/{row.place.replace(' ', '_')}", row.gain, 0)
    writer.add_text("diagnose/verdict", diagnosis.verdict, 0)
    writer.add_text("diagnose/final_model", f"    {diagnosis.ladder.final.describe()}".replace("\n", "\n    "), 0)
    writer.close()


def _table(header: list[str], rows: list[list]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _parameter_table(score: ModelScore) -> str:
    """The fitted model's parameters as an HTML table: value, standard error and 95 % interval where fitted."""
    def spread(row: dict) -> list[str]:
        if "std" not in row:
            return ["", ""]
        low, high = row["interval"]
        return [f"{row['std']:.3g}", f"[{low:.4g}, {high:.4g}]"]

    return _table(["parameter", "value", "± std", "95 % interval", "unit", "constraint", "status", "meaning"],
                  [[r["name"], f"{r['value']:.6g}", *spread(r), r["unit"], r["constraint"],
                    "learned" if r["learnable"] else "fixed", r["meaning"]] for r in score.rows()])


def _pct(value: float | None) -> str:
    return "—" if value is None else f"{100 * value:.2f}"


def _discovery_section(found: dict | None) -> str:
    if found is None:
        return ""
    rows = [[key.replace("_", " "), _pct(value)] for key, value in found["nrmse_validation"].items()]
    judged = "recommended" if found["recommended"] else "not recommended"
    return (f"<h2>5. Discovery: a force outside the library</h2><p>Closed form of the learned force: "
            f"<code>{html.escape(str(found['expression']))}</code> ({judged}: {html.escape(found['reason'])}). Best "
            f"library effect: {html.escape(str(found['library_best']))}.</p>" + _table(["model", "validation %"], rows))


def _probes_section(found: dict | None) -> str:
    if found is None:
        return ""
    if not found["probes"]:
        return f"<h2>6. Where the mismatch points</h2><p>Not probed: {html.escape(found['reason'] or '')}.</p>"
    best = "none of the places" if found["best"] is None else f"the <b>{html.escape(found['best'])}</b>"
    rows = [[r["place"], r["extension"], r["fitted"] or "—", _pct(r["nrmse_validation"]),
             "—" if r["gain"] is None else f"{100 * r['gain']:.1f}", r["note"]] for r in found["probes"]]
    return (f"<h2>6. Where the mismatch points</h2><p>One small extension refitted at each place, scored on "
            f"validation against {html.escape(found['model'])} ({_pct(found['nrmse_validation'])} %); it points at "
            f"{best}. In time: {html.escape(found['in_time']['description'])}.</p>"
            + _table(["place", "extension", "fitted", "validation %", "gain %", "what was fitted"], rows))


def _html(diagnosis: Diagnosis, content: dict, figures: list[str]) -> str:
    base = content["baseline"]
    ranking = _table(
        ["rank", "effect", "score", "validation %", f"Δ{diagnosis.ranking.rule.criterion.upper()} (criterion gain)",
         "parameters", "refit"],
        [[i, e["effect"], f"{e['score']:.3f}", "undecided" if e["undecided"] is not None else _pct(e["nrmse_validation"]),
          "" if e["improvement"] is None else f"{e['improvement']:.1f}",
          ", ".join(f"{k}={v:.4g}" for k, v in e["parameters"].items())
          + "".join(f" (unphysical: {note})" for note in e["unphysical"])
          + (f" ({e['failure']})" if e["failure"] else ""), e["refit_reason"]]
         for i, e in enumerate(content["ranking"], 1)],
    )
    ladder = _table(["step", "model", "train %", "validation %"],
                    [[i, s["equation"], _pct(s["nrmse_train"]), _pct(s["nrmse_validation"])]
                     for i, s in enumerate(content["ladder"])])
    hybrid = _table(["model", "physics train %", "hybrid train %", "physics validation %", "hybrid validation %",
                     "verdict"],
                    [[h["model"], _pct(h["physics_nrmse_train"]), _pct(h["nrmse_train"]),
                      _pct(h["physics_nrmse_validation"]), _pct(h["nrmse_validation"]), h["message"]]
                     for h in content["hybrid"]])
    discovery = _discovery_section(content["discovery"]) + _probes_section(content["where_the_mismatch_points"])
    channels = content["where_it_fails"]["channels"]
    per_output = "" if len(channels) < 2 else (
        f"<p>Per output channel (validation): the missing effect shows most at output "
        f"<b>{html.escape(content['where_it_fails']['shows_most'])}</b>.</p>"
        + _table(["output", "physics %", "final %", "physics RMSE", "final RMSE"],
                 [[c["name"], _pct(c["nrmse_validation_physics"]), _pct(c["nrmse_validation_final"]),
                   f"{c['rmse_validation_physics']:.4g}", f"{c['rmse_validation_final']:.4g}"] for c in channels]))
    if content["undecided"]:
        ranking += "<p><b>Undecided</b> (refits stopped over budget; the verdict names the option that decides them):</p>"
        ranking += _table(["model", "effect", "seconds"],
                          [[u["model"], u["effect"], f"{u['seconds']:.1f}"] for u in content["undecided"]])
    images = "".join(f'<h3>{name}</h3><img src="figures/{name}.png" alt="{name}">' for name in figures)
    final = f"<p>{html.escape(diagnosis.ladder.final.equation)}</p>{_parameter_table(diagnosis.ladder.final)}"
    warning = diagnosis.ladder.final.warning
    if warning is not None:
        final += f"<p><b>Identifiability.</b> {html.escape(warning)}</p>"
    return f"""<!doctype html>
<html><head><meta charset="utf-8"><title>torchpaml diagnosis</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}} td,th{{border:1px solid #ccc;padding:3px 6px}}
table{{border-collapse:collapse}} img{{max-width:100%}}</style></head><body>
<h1>Diagnosis of {html.escape(base['model'])}</h1>
<p><b>Verdict.</b> {html.escape(content['verdict'])}</p>
<h2>1. Compare</h2><p>Fitted physics: training mismatch {_pct(base['nrmse_train'])} %, validation
{_pct(base['nrmse_validation'])} %.</p>{per_output}
<h2>2. Which effect is missing</h2>{ranking}
<h2>3. Model ladder</h2>{ladder}<p>The final model, with standard errors and 95 % intervals from the
Jacobian at the optimum (valid for a white residual):</p>{final}
<h2>4. The Chebyshev residual on top</h2>{hybrid}
{discovery}
<h2>Figures</h2>{images}
</body></html>
"""
