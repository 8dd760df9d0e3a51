"""Diagnostics: how the physics compares with the measurements, and where it fails."""

from torchpaml.diagnostics.adequacy import Adequacy, assess_adequacy
from torchpaml.diagnostics.compare import Comparison, compare
from torchpaml.diagnostics.harmonics import HarmonicFingerprint, harmonic_fingerprint
from torchpaml.diagnostics.ranking import (
    EffectEvidence,
    ModelScore,
    Ranking,
    rank_missing_effects,
)
from torchpaml.diagnostics.residuals import ResidualAnalysis, residual_analysis
from torchpaml.diagnostics.validity import (
    AmplitudeBins,
    ValidityMap,
    error_by_amplitude,
    validity_map,
)

__all__ = [
    "Adequacy",
    "AmplitudeBins",
    "Comparison",
    "EffectEvidence",
    "HarmonicFingerprint",
    "ModelScore",
    "Ranking",
    "ResidualAnalysis",
    "ValidityMap",
    "assess_adequacy",
    "compare",
    "error_by_amplitude",
    "harmonic_fingerprint",
    "rank_missing_effects",
    "residual_analysis",
    "validity_map",
]
