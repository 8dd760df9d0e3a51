"""The analyses a diagnosis composes, each usable alone: where and how the physics fails (comparison, residual
analysis, error by amplitude, validity map, harmonic fingerprint, adequacy), the orthogonal residual's hybrid and
certificates, and the stages' one-call conveniences (``rank_missing_effects`` is ``Ranker(...).rank(...)``,
``discover_missing_force`` is ``Discoverer(...).discover(...)``)."""

from torchpaml._certificates import Certificate, incompatibility_certificates
from torchpaml._diagnostics import (
    AmplitudeBins,
    Comparison,
    HarmonicFingerprint,
    ResidualAnalysis,
    ValidityMap,
    assess_adequacy,
    compare,
    discover_missing_force,
    error_by_amplitude,
    harmonic_fingerprint,
    hybrid_residual,
    model_ladder,
    rank_missing_effects,
    residual_analysis,
    validity_map,
)

__all__ = ["AmplitudeBins", "Certificate", "Comparison", "HarmonicFingerprint", "ResidualAnalysis", "ValidityMap",
           "assess_adequacy", "compare", "discover_missing_force", "error_by_amplitude", "harmonic_fingerprint",
           "hybrid_residual", "incompatibility_certificates", "model_ladder", "rank_missing_effects",
           "residual_analysis", "validity_map"]
