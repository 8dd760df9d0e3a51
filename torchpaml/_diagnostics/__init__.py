"""Diagnostics: how the physics compares with the measurements, where it fails, and which effect is missing."""

from torchpaml._diagnostics.adequacy import Adequacy, assess_adequacy
from torchpaml._diagnostics.compare import Comparison, compare
from torchpaml._diagnostics.discoverer import Discoverer
from torchpaml._diagnostics.discovery import Discovery
from torchpaml._diagnostics.discoverer import discover_missing_force
from torchpaml._diagnostics.diagnosis import Diagnosis, HybridScore, diagnose, hybrid_residual
from torchpaml._diagnostics.harmonics import HarmonicFingerprint, harmonic_fingerprint
from torchpaml._diagnostics.ladder import Ladder, model_ladder
from torchpaml._diagnostics.ranker import Ranker
from torchpaml._diagnostics.ranker import rank_missing_effects
from torchpaml._diagnostics.results import EffectEvidence, ModelScore, Ranking
from torchpaml._diagnostics.selection import SelectionRule
from torchpaml._diagnostics.residuals import ResidualAnalysis, residual_analysis
from torchpaml._diagnostics.validity import (
    AmplitudeBins,
    ValidityMap,
    error_by_amplitude,
    validity_map,
)

__all__ = [
    "SelectionRule",
    "Adequacy",
    "AmplitudeBins",
    "Comparison",
    "Diagnosis",
    "Discoverer",
    "Discovery",
    "EffectEvidence",
    "HarmonicFingerprint",
    "HybridScore",
    "Ladder",
    "ModelScore",
    "Ranker",
    "Ranking",
    "ResidualAnalysis",
    "ValidityMap",
    "assess_adequacy",
    "compare",
    "diagnose",
    "discover_missing_force",
    "error_by_amplitude",
    "harmonic_fingerprint",
    "hybrid_residual",
    "model_ladder",
    "rank_missing_effects",
    "residual_analysis",
    "validity_map",
]
