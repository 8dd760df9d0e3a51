"""Diagnostics: how the physics compares with the measurements, where it fails, and which effect is missing."""

from torchpaml._diagnostics.analysis.adequacy import Adequacy, assess_adequacy
from torchpaml._diagnostics.analysis.compare import Comparison, compare
from torchpaml._diagnostics.discovery.discoverer import Discoverer
from torchpaml._diagnostics.discovery.result import Discovery
from torchpaml._diagnostics.discovery.discoverer import discover_missing_force
from torchpaml._diagnostics.diagnosis import Diagnosis, HybridScore, diagnose, hybrid_residual
from torchpaml._diagnostics.mismatch.in_time import ErrorInTime, error_in_time
from torchpaml._diagnostics.mismatch.places import PLACES, Place
from torchpaml._diagnostics.mismatch.prober import Prober
from torchpaml._diagnostics.mismatch.result import MismatchProbes, ProbeResult
from torchpaml._diagnostics.analysis.harmonics import HarmonicFingerprint, harmonic_fingerprint
from torchpaml._diagnostics.ranking.ladder import Ladder, model_ladder
from torchpaml._diagnostics.ranking.ranker import Ranker
from torchpaml._diagnostics.ranking.ranker import rank_missing_effects
from torchpaml._diagnostics.results import EffectEvidence, ModelScore, Ranking
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._diagnostics.analysis.residuals import ResidualAnalysis, residual_analysis
from torchpaml._diagnostics.analysis.validity import (
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
    "ErrorInTime",
    "HarmonicFingerprint",
    "HybridScore",
    "Ladder",
    "MismatchProbes",
    "ModelScore",
    "PLACES",
    "Place",
    "ProbeResult",
    "Prober",
    "Ranker",
    "Ranking",
    "ResidualAnalysis",
    "ValidityMap",
    "assess_adequacy",
    "compare",
    "diagnose",
    "discover_missing_force",
    "error_by_amplitude",
    "error_in_time",
    "harmonic_fingerprint",
    "hybrid_residual",
    "model_ladder",
    "rank_missing_effects",
    "residual_analysis",
    "validity_map",
]
