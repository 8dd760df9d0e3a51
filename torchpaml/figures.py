"""The figures of a diagnosis, one function each, returning a matplotlib ``Figure`` (``import torchpaml.figures``)."""

from torchpaml._render.figures import (
    amplitude_figure,
    comparison_figure,
    diagnosis_figures,
    discovery_figure,
    fleet_figure,
    ladder_figure,
    overlay_figure,
    ranking_figure,
    residual_analysis_figure,
    residual_figure,
    spectrum_figure,
    validity_figure,
)

__all__ = ["amplitude_figure", "comparison_figure", "diagnosis_figures", "discovery_figure", "fleet_figure",
           "ladder_figure", "overlay_figure", "ranking_figure", "residual_analysis_figure", "residual_figure",
           "spectrum_figure", "validity_figure"]
