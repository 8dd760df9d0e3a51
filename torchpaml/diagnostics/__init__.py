"""Diagnostics: how the physics compares with the measurements, and where it fails."""

from torchpaml.diagnostics.compare import Comparison, compare
from torchpaml.diagnostics.harmonics import HarmonicFingerprint, harmonic_fingerprint
from torchpaml.diagnostics.residuals import ResidualAnalysis, residual_analysis

__all__ = ["Comparison", "compare", "HarmonicFingerprint", "harmonic_fingerprint", "ResidualAnalysis", "residual_analysis"]
