"""Markdown tables of result objects: the comparison, the ranking, and the paper reproduction."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from torchpaml._diagnostics import Comparison, Ranking

__all__ = ["comparison_table", "paper_table", "ranking_table"]


def comparison_table(comparison: Comparison) -> str:
    """The scores of :func:`~torchpaml.compare`: mismatch %, fit % and RMSE per experiment and model."""
    lines = ["| experiment | model | mismatch % | fit % | RMSE |", "|---|---|---|---|---|"]
    for r in comparison.rows:
        lines.append(f"| {r['experiment']} | {r['model']} | {r['mismatch_pct']:.2f} | {r['fit_pct']:.2f} "
                     f"| {r['rmse']:.4g} |")
    return "\n".join(lines)


def ranking_table(ranking: Ranking) -> str:
    """A ranking's baseline, then per candidate: score, validation mismatch, criterion gain, fitted parameters, and
    why it was or was not refitted."""
    head = (f"baseline {ranking.baseline.name}: train {100 * ranking.baseline.nrmse_train:.2f} %, "
            f"validation {100 * ranking.baseline.nrmse_validation:.2f} %")
    if ranking.skipped:
        head += "\nskipped (do not apply): " + "; ".join(f"{k}: {v}" for k, v in ranking.skipped.items())
    if ranking.simpler:
        head += f"\n{ranking.simpler}"
    if ranking.equivalent:
        head += f"\nthe same evidence as the first (the records cannot tell them apart): {', '.join(ranking.equivalent)}"
    lines = [head, "",
             f"| rank | effect | score | validation % | Δ{ranking.rule.criterion.upper()} | parameters | refit |",
             "|---|---|---|---|---|---|---|"]
    for i, e in enumerate(ranking.entries, 1):
        refit = e.refit
        validation = ("undecided" if e.undecided is not None else "not refitted") if refit is None else \
            f"{100 * refit.nrmse_validation:.2f}"
        gain = "" if e.improvement is None else f"{e.improvement:.1f}"
        params = "" if refit is None else ", ".join(f"{k}={v:.4g}" for k, v in refit.parameters.items())
        params += "".join(f" **unphysical: {note}**" for note in e.unphysical)
        params += f" **{e.failure}**" if e.failure else ""
        lines.append(f"| {i} | {e.effect} | {e.score:.3f} | {validation} | {gain} | {params} | {e.refit_reason} |")
    return "\n".join(lines)


def paper_table(report: dict) -> str:
    """The paper reproduction (``torchpaml paper``'s ``results.json``): ours (mean ± std over seeds) beside the
    paper's numbers, then the certificates."""
    rows = [
        ("ζ̂", ("zeta_hat",), "{:.4f}"),
        ("physical ID mismatch %", ("physical_id_mismatch",), "{:.2f}"),
        ("residual ID: physics %", ("residual_id", "physics"), "{:.2f}"),
        ("residual ID: hybrid %", ("residual_id", "hybrid"), "{:.2f}"),
        ("validation: physics %", ("validation", "physics"), "{:.2f}"),
        ("validation: hybrid %", ("validation", "hybrid"), "{:.2f}"),
        ("Δζ (first-order check)", ("delta_zeta",), "{:.5f}"),
    ]
    alphas = list(report["results"])
    head = "| quantity | " + " | ".join(f"α={a} ours | α={a} paper" for a in alphas) + " |"
    lines = [head, "|" + "---|" * (1 + 2 * len(alphas))]
    for label, path, fmt in rows:
        cells = []
        for a in alphas:
            ours = report["results"][a]
            paper = report["paper"].get(a, {})
            for key in path:
                ours, paper = ours[key], (paper or {}).get(key)
            spread = f" ± {fmt.format(ours['std'])}" if ours["std"] > 0 else ""
            cells += [fmt.format(ours["mean"]) + spread, "—" if paper is None else fmt.format(paper)]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    first = next(iter(next(iter(report["results"].values()))["certificates"].values()))
    lines += ["", "Incompatibility certificates on α·cos(ωt), worst |c0| / |c1| over random residual draws:", ""]
    lines += ["| α | residual | " + " | ".join(f"T={r['T']:g}" for r in first) + " |"]
    lines += ["|---|---|" + "---|" * len(first)]
    for a in alphas:
        for name, certificates in report["results"][a]["certificates"].items():
            cells = [f"{r['zeroth_max']:.1e} / {r['first_max']:.1e}" for r in certificates]
            lines.append(f"| {a} | {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
