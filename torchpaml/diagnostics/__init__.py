"""Diagnostics: how the physics compares with the measurements, and where it fails."""

from torchpaml.diagnostics.compare import Comparison, compare
from torchpaml.diagnostics.residuals import ResidualAnalysis, residual_analysis

__all__ = ["Comparison", "compare", "ResidualAnalysis", "residual_analysis"]
