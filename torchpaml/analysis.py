"""The analyses a diagnosis composes, each usable alone: where and how the physics fails (comparison, residual
analysis, error by amplitude, validity map, harmonic fingerprint, adequacy, where in time the error sits, the
places a probe extends the physics at), the orthogonal residual's hybrid and
certificates, and the stages' one-call conveniences (``rank_missing_effects`` is ``Ranker(...).rank(...)``,
``discover_missing_force`` is ``Discoverer(...).discover(...)``)."""

from torchpaml._certificates import Certificate, incompatibility_certificates
from torchpaml._diagnostics import (
    AmplitudeBins,
    Comparison,
    ErrorInTime,
    HarmonicFingerprint,
    PLACES,
    Place,
    ProbeResult,
    ResidualAnalysis,
    ValidityMap,
    assess_adequacy,
    compare,
    discover_missing_force,
    error_by_amplitude,
    error_in_time,
    harmonic_fingerprint,
    hybrid_residual,
    model_ladder,
    rank_missing_effects,
    residual_analysis,
    validity_map,
)

__all__ = ["AmplitudeBins", "Certificate", "Comparison", "ErrorInTime", "HarmonicFingerprint", "PLACES", "Place",
           "ProbeResult", "ResidualAnalysis", "ValidityMap", "assess_adequacy", "compare", "discover_missing_force",
           "error_by_amplitude", "error_in_time", "harmonic_fingerprint",
           "hybrid_residual", "incompatibility_certificates", "model_ladder", "rank_missing_effects",
           "residual_analysis", "validity_map"]
