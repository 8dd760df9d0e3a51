r"""Pure functions from signals to matplotlib figures; the same figures serve notebooks, TensorBoard and reports.

Signals are 1-D tensors or arrays over a time grid ``t`` (time,) in s. The figures are made with the
object-oriented API (no pyplot state), so they are safe in a headless training process.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from matplotlib.figure import Figure

__all__ = ["overlay_figure", "residual_figure", "spectrum_figure", "dominant_frequency"]


def _numpy(x) -> np.ndarray:
    return x.detach().cpu().numpy().reshape(-1) if isinstance(x, torch.Tensor) else np.asarray(x).reshape(-1)


def overlay_figure(t, measured, models: dict, title: str = "") -> Figure:
    """Measured output and each model's output over time (``models``: label -> signal)."""
    fig = Figure(figsize=(9, 3.2), tight_layout=True)
    ax = fig.add_subplot()
    t = _numpy(t)
    ax.plot(t, _numpy(measured), color="black", lw=1.2, label="measured")
    for label, signal in models.items():
        ax.plot(t, _numpy(signal), lw=1.0, label=label)
    ax.set(xlabel="t [s]", ylabel="y", title=title or "measured vs models")
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


def dominant_frequency(t, u) -> float:
    """The frequency (rad/s) of the largest non-DC line of ``u``'s amplitude spectrum."""
    t, u = _numpy(t), _numpy(u)
    spectrum = np.abs(np.fft.rfft(u - u.mean()))
    frequencies = 2 * math.pi * np.fft.rfftfreq(len(u), d=float(t[1] - t[0]))
    return float(frequencies[1 + int(np.argmax(spectrum[1:]))])


def spectrum_figure(t, residual, drive: float, harmonics: int = 15, title: str = "") -> Figure:
    r"""Amplitude spectrum of a residual, with the harmonics $k\omega$ of the drive marked (odd solid, even dashed).

    ``drive`` is the drive's fundamental in rad/s (see :func:`dominant_frequency`).
    """
    t, r = _numpy(t), _numpy(residual)
    amplitude = 2 * np.abs(np.fft.rfft(r)) / len(r)
    frequencies = 2 * math.pi * np.fft.rfftfreq(len(r), d=float(t[1] - t[0]))
    top = min(frequencies[-1], (harmonics + 0.5) * drive)
    keep = frequencies <= top
    fig = Figure(figsize=(9, 3.2), tight_layout=True)
    ax = fig.add_subplot()
    ax.semilogy(frequencies[keep], amplitude[keep] + 1e-300, color="black", lw=1.0)
    for k in range(1, harmonics + 1):
        if k * drive <= top:
            ax.axvline(k * drive, color="tab:red" if k % 2 else "tab:blue", lw=0.8, ls="-" if k % 2 else "--")
    ax.set(xlabel="ω [rad/s]", ylabel="|R(ω)|", title=title or f"residual spectrum, drive harmonics kω (ω = {drive:.3g})")
    return fig
