r"""Pure functions from signals and result objects to matplotlib figures.

The same figures serve notebooks, TensorBoard and the diagnosis report. Signals are 1-D tensors or
arrays over a time grid ``t`` (time,) in s. Result objects are the plain dataclasses of the
diagnostics (:class:`~torchpaml.Comparison`, :class:`~torchpaml.Ranking`, ...); they carry their
outputs, so drawing them simulates nothing. The figures are made with the object-oriented API (no
pyplot state), so they are safe in a headless training process.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch
from matplotlib.figure import Figure

from torchpaml._signals import amplitude_spectrum

if TYPE_CHECKING:
    from torchpaml._diagnostics import (
        AmplitudeBins,
        Comparison,
        Diagnosis,
        Discovery,
        Ladder,
        ModelScore,
        Ranking,
        ResidualAnalysis,
        ValidityMap,
    )
    from torchpaml._diagnostics.analysis.spread import ParameterSpread

__all__ = [
    "amplitude_figure",
    "comparison_figure",
    "diagnosis_figures",
    "discovery_figure",
    "fleet_figure",
    "ladder_figure",
    "overlay_figure",
    "ranking_figure",
    "residual_analysis_figure",
    "residual_figure",
    "spectrum_figure",
    "validity_figure",
]


def _numpy(x) -> np.ndarray:
    return x.detach().cpu().numpy().reshape(-1) if isinstance(x, torch.Tensor) else np.asarray(x).reshape(-1)


def overlay_figure(t, measured, models: dict, title: str = "", ylabel: str = "y") -> Figure:
    """Measured output and each model's output over time (``models``: label -> signal), the y-axis named
    ``ylabel`` (the output channel's name)."""
    fig = Figure(figsize=(9, 3.2), tight_layout=True)
    ax = fig.add_subplot()
    t = _numpy(t)
    ax.plot(t, _numpy(measured), color="black", lw=1.2, label="measured")
    for label, signal in models.items():
        ax.plot(t, _numpy(signal), lw=1.0, label=label)
    ax.set(xlabel="t [s]", ylabel=ylabel, title=title or "measured vs models")
    ax.legend(loc="upper right", fontsize=8)
    return fig


def residual_figure(t, actual, predicted, title: str = "") -> Figure:
    r"""The residual the data demand, $y - \hat y$, against the one the residual model predicts, $r$."""
    fig = Figure(figsize=(9, 3.2), tight_layout=True)
    ax = fig.add_subplot()
    t = _numpy(t)
    ax.plot(t, _numpy(actual), color="black", lw=1.2, label="actual y − ŷ")
    ax.plot(t, _numpy(predicted), lw=1.0, label="predicted r")
    ax.set(xlabel="t [s]", ylabel="residual", title=title or "actual vs predicted residual")
    ax.legend(loc="upper right", fontsize=8)
    return fig


def spectrum_figure(t, residual, drive: float, harmonics: int = 15, title: str = "") -> Figure:
    r"""Amplitude spectrum of a residual, with the harmonics $k\omega$ of the drive marked (odd solid, even dashed).

    ``drive`` is the drive's fundamental in rad/s (see :func:`~torchpaml._signals.dominant_frequency`); the spectrum
    is :func:`~torchpaml._signals.amplitude_spectrum`'s.
    """
    frequencies, amplitude = amplitude_spectrum(_numpy(t), _numpy(residual))
    top = min(frequencies[-1], (harmonics + 0.5) * drive)
    keep = frequencies <= top
    fig = Figure(figsize=(9, 3.2), tight_layout=True)
    ax = fig.add_subplot()
    ax.semilogy(frequencies[keep], amplitude[keep] + 1e-300, color="black", lw=1.0)
    for k in range(1, harmonics + 1):
        if k * drive <= top:
            ax.axvline(k * drive, color="tab:red" if k % 2 else "tab:blue", lw=0.8, ls="-" if k % 2 else "--")
    ax.set(xlabel="ω [rad/s]", ylabel="|R(ω)|",
           title=title or f"residual spectrum, drive harmonics kω (ω = {drive:.3g})")
    return fig


def comparison_figure(comparison: Comparison, experiment: str | None = None) -> Figure:
    """Measured vs every model of :func:`~torchpaml.compare` on one experiment (default: the first)."""
    name = experiment or next(iter(comparison.experiments))
    record = comparison.experiments[name]
    labels = {f"{m} ({comparison.fit(name, m):.1f} % fit)": y for m, y in comparison.outputs[name].items()}
    return overlay_figure(record.t, record.y[:, 0], labels, f"compare: {name}")


def residual_analysis_figure(analysis: ResidualAnalysis) -> Figure:
    """The two correlations of :func:`~torchpaml.residual_analysis`, their bounds shaded, as ``resid`` draws them."""
    fig = Figure(figsize=(9, 5), tight_layout=True)
    top, bottom = fig.subplots(2, 1)
    for ax, lags, values, bound, title in (
        (top, analysis.lags, analysis.autocorrelation, analysis.autocorrelation_bound, "autocorrelation of e"),
        (bottom, analysis.cross_lags, analysis.cross_correlation, analysis.cross_correlation_bound,
         "cross-correlation of the prewhitened u and e"),
    ):
        ax.axhspan(-bound, bound, color="tab:blue", alpha=0.15, label=f"{100 * analysis.confidence:g} % bound")
        ax.stem(lags, values, basefmt=" ")
        ax.set(title=title, xlabel="lag [samples]")
        ax.legend(loc="upper right", fontsize=8)
    return fig


def validity_figure(validity: ValidityMap, threshold: float = 0.1) -> Figure:
    """Heat map of :func:`~torchpaml.validity_map` in %, cells above ``threshold`` marked (where the physics breaks)."""
    fig = Figure(figsize=(6, 4), tight_layout=True)
    ax = fig.add_subplot()
    image = ax.imshow(100 * validity.mismatch, origin="lower", aspect="auto", cmap="viridis")
    for i in range(len(validity.amplitudes)):
        for j in range(len(validity.frequencies)):
            value = validity.mismatch[i, j]
            ax.text(j, i, f"{100 * value:.0f}", ha="center", va="center", fontsize=7,
                    color="red" if value > threshold else "white")
    ax.set_xticks(range(len(validity.frequencies)), [f"{f:g}" for f in validity.frequencies])
    ax.set_yticks(range(len(validity.amplitudes)), [f"{a:g}" for a in validity.amplitudes])
    ax.set(xlabel="ω [rad/s]", ylabel="amplitude α", title="physics mismatch % per sine test")
    fig.colorbar(image, ax=ax, label="mismatch %")
    return fig


def amplitude_figure(by_input: AmplitudeBins, by_output: AmplitudeBins) -> Figure:
    """Bars of :func:`~torchpaml.error_by_amplitude`: the mismatch within bins of |u| and of |y|."""
    fig = Figure(figsize=(9, 3.5), layout="constrained")
    for ax, bins, label in zip(fig.subplots(1, 2), (by_input, by_output), ("|u|", "|y|"), strict=True):
        centers = (bins.edges[1:] + bins.edges[:-1]) / 2
        ax.bar(centers, 100 * bins.mismatch, width=0.9 * (bins.edges[1] - bins.edges[0]))
        ax.set_xlabel(f"{label} bin")
        ax.set_ylabel("mismatch in bin (%)")
    fig.suptitle("where the fitted physics fails (validation)")
    return fig


def ranking_figure(ranking: Ranking) -> Figure:
    """Bars: each candidate's first-order score, and the validation mismatch of the refitted ones."""
    fig = Figure(figsize=(9, 4), layout="constrained")
    left, right = fig.subplots(1, 2)
    names = [e.effect for e in ranking.entries]
    left.barh(names[::-1], [e.score for e in ranking.entries][::-1], color="tab:blue")
    left.set_xlabel("first-order score (share of residual energy)")
    refitted = [e for e in ranking.entries if e.refit is not None]
    right.barh([e.effect for e in refitted][::-1], [100 * e.refit.nrmse_validation for e in refitted][::-1],
               color="tab:orange")
    right.axvline(100 * ranking.baseline.nrmse_validation, color="k", linestyle="--", label="baseline")
    right.set_xlabel("validation mismatch after refit (%)")
    right.legend()
    fig.suptitle(f"missing-effect ranking on {ranking.baseline.name}")
    return fig


def ladder_figure(ladder: Ladder, discovered: ModelScore | None = None) -> Figure:
    """Validation and training mismatch per rung of :func:`~torchpaml.model_ladder`, on a log scale.

    ``discovered``: the physics with the discovered force (:func:`~torchpaml.discover_missing_force`),
    drawn as a rung of its own.
    """
    fig = Figure(figsize=(7, 4), layout="constrained")
    ax = fig.subplots()
    labels = ["physics", *(f"+ {name}" + ("" if gone is None else f" - {gone}")
                           for name, gone in zip(ladder.added, ladder.removed + [None] * len(ladder.added)))]
    steps = range(len(ladder.steps))
    ax.semilogy(steps, [100 * s.nrmse_validation for s in ladder.steps], "o-", label="validation")
    ax.semilogy(steps, [100 * s.nrmse_train for s in ladder.steps], "s--", label="training")
    if discovered is not None:
        last = len(ladder.steps)
        ax.semilogy([last], [100 * discovered.nrmse_validation], "D", color="tab:red", label="physics + discovered")
        ax.semilogy([last], [100 * discovered.nrmse_train], "x", color="tab:red")
        labels.append("physics\n+ discovered")
        steps = range(last + 1)
    ax.set_xticks(list(steps), labels)
    ax.set_ylabel("mismatch (%)")
    ax.set_title("model ladder")
    ax.legend()
    return fig


def discovery_figure(discovery: Discovery) -> Figure:
    """The learned rate of the first equation against each variable along the training trajectory, the closed form
    overlaid."""
    s = discovery.samples
    variables = [k for k in s if k not in ("learned", "closed_form")]
    fig = Figure(figsize=(3.7 * len(variables), 3.6), layout="constrained")
    for ax, name in zip(fig.subplots(1, len(variables), sharey=True, squeeze=False)[0], variables, strict=True):
        ax.plot(s[name], s["learned"], ".", ms=3, alpha=0.5, label="learned rate (MLP)")
        ax.plot(s[name], s["closed_form"], ".", ms=3, alpha=0.5, label="closed form")
        ax.set_xlabel(name)
    fig.axes[0].set_ylabel("rate of the first equation")
    fig.axes[0].legend(fontsize=8)
    fig.suptitle(f"discovered: {discovery.text}" + (" (recommended)" if discovery.recommended else ""))
    return fig


def _channel_figures(diagnosis: Diagnosis) -> dict[str, Figure]:
    """``compare``, ``residual_analysis`` and ``error_by_amplitude`` of each output channel: under these names for
    one output, with the channel's name appended (``compare_y2``) for several."""
    record, several = diagnosis.validation[0], len(diagnosis.channels) > 1
    figures = {}
    for c, channel in enumerate(diagnosis.channels):
        suffix, scores = (f"_{channel.name}", (channel.physics, channel.final)) if several else ("", None)
        outputs = {f"{s.name} ({100 * (s.nrmse_validation if scores is None else score):.2f} %)":
                   s.validation_outputs[0][:, c] for s, score in zip(diagnosis.compared_models, scores or (0, 0))}
        where = f"output {channel.name}, " if several else ""
        figures[f"compare{suffix}"] = overlay_figure(record.t, record.y[:, c], outputs,
                                                     f"measured vs models, {where}validation record {record.name!r}",
                                                     channel.name)
        figures[f"residual_analysis{suffix}"] = residual_analysis_figure(channel.residuals)
        figures[f"error_by_amplitude{suffix}"] = amplitude_figure(channel.by_input, channel.by_output)
    return figures


def diagnosis_figures(diagnosis: Diagnosis) -> dict[str, Figure]:
    """Name -> figure of a :class:`~torchpaml.Diagnosis`: ``compare``, ``residual_analysis``,
    ``error_by_amplitude`` (for each output channel, ``compare_y1``, ``compare_y2``, ..., where there are several),
    ``ranking``, ``ladder``, and ``discovery`` when it searched."""
    figures = {
        **_channel_figures(diagnosis),
        "ranking": ranking_figure(diagnosis.ranking),
        "ladder": ladder_figure(diagnosis.ladder,
                                None if diagnosis.discovery is None else diagnosis.discovery.discovered),
    }
    if diagnosis.discovery is not None and diagnosis.discovery.searched:
        figures["discovery"] = discovery_figure(diagnosis.discovery)
    return figures


def fleet_figure(spreads: list[ParameterSpread]) -> Figure:
    """Each parameter across a fleet: every unit's estimate ± 3 standard errors, the fleet's median, its reach
    (median ± 3 robust spreads), and the units that stand out in red, by name."""
    fig = Figure(figsize=(9, 2.6 * max(1, len(spreads))), layout="constrained")
    axes = fig.subplots(max(1, len(spreads)), 1, squeeze=False)[:, 0]
    for ax, spread in zip(axes, spreads, strict=False):
        x = np.arange(len(spread.units))
        out = np.array([u in spread.outliers for u in spread.units])
        ax.axhspan(spread.median - 3 * spread.sigma, spread.median + 3 * spread.sigma, color="tab:blue", alpha=0.12,
                   label="median ± 3 robust spreads")
        ax.axhline(spread.median, color="tab:blue", lw=1.0)
        bars = np.where(np.isfinite(spread.stds), 3 * spread.stds, 0.0)  # an undetermined parameter: no bar
        ax.errorbar(x[~out], spread.values[~out], bars[~out], fmt="o", color="black", ms=4, label="unit")
        ax.errorbar(x[out], spread.values[out], bars[out], fmt="o", color="tab:red", ms=5,
                    label="stands out")
        for i in np.flatnonzero(out):
            ax.annotate(spread.units[i], (x[i], spread.values[i]), textcoords="offset points", xytext=(4, 4),
                        color="tab:red", fontsize=8)
        ax.set_xticks(x, spread.units, rotation=45, fontsize=7)
        ax.set_ylabel(spread.name)
    axes[0].legend(fontsize=7, loc="upper right")
    fig.suptitle("fitted parameters across the fleet")
    return fig
