"""torchpaml: physics-augmented learning of input-driven dynamical systems, with orthogonal residuals.

Fit an ODE physics model to measurements u(t), y(t), see where it fails, find the physical effect it
misses, add it, and put a Chebyshev-Hammerstein residual on top that improves accuracy but cannot hide
wrong physics (Kuang & Lin, "Structural Constraints for Physics-augmented Learning").

Everything a user calls is exported here; the modules behind it are private. The command line is
``torchpaml`` (:mod:`torchpaml.cli`). The Lightning systems load Lightning on first use.
"""

import importlib

from torchpaml._certificates import Certificate, incompatibility_certificates
from torchpaml._data import Experiment, ExperimentSource, Files, Record, RecordSource, Simulated, simulate_record
from torchpaml._diagnostics import (
    SelectionRule,
    Adequacy,
    AmplitudeBins,
    Comparison,
    Diagnosis,
    Discoverer,
    Discovery,
    EffectEvidence,
    HarmonicFingerprint,
    HybridScore,
    Ladder,
    ModelScore,
    Ranker,
    Ranking,
    ResidualAnalysis,
    ValidityMap,
    assess_adequacy,
    compare,
    diagnose,
    discover_missing_force,
    error_by_amplitude,
    harmonic_fingerprint,
    hybrid_residual,
    model_ladder,
    rank_missing_effects,
    residual_analysis,
    validity_map,
)
from torchpaml._errors import (
    ConfigurationError,
    DataError,
    DomainError,
    PhysicsError,
    ResolutionError,
    SimulationError,
    TorchpamlError,
)
from torchpaml._fit import (
    Estimate,
    InitialState,
    PhysicsEstimate,
    Rest,
    ResidualEstimate,
    SparseRegression,
    estimate_initial_state,
    fit_chebyshev_hammerstein,
    fit_neural_force,
    fit_physics,
    fit_residual,
    reestimate_shift,
)
from torchpaml._budget import Budget, OverBudget
from torchpaml._fit.uncertainty import IdentifiabilityWarning, Uncertainty
from torchpaml._metrics import channel_mismatch, fit_percent, mismatch, rmse
from torchpaml._parameters import Interval, PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics import (
    EFFECTS,
    AbstractEffect,
    AbstractPhysics,
    ComposedModel,
    ConstantForce,
    CoulombFriction,
    CubicStiffness,
    DeadZone,
    DynamicFriction,
    EffectState,
    Hysteresis,
    InputLag,
    DiscoveredForce,
    InputSaturation,
    Oscillator,
    OutputSaturation,
    Pendulum,
    PendulumRestoring,
    QuadraticDamping,
    QuadraticStiffness,
    SecondOrderPhysics,
    TermLibrary,
    default_effects,
    complete_state,
    state_vector,
)
from torchpaml._physics.registry import PHYSICS, build_model
from torchpaml._render.figures import (
    amplitude_figure,
    comparison_figure,
    diagnosis_figures,
    discovery_figure,
    ladder_figure,
    overlay_figure,
    ranking_figure,
    residual_analysis_figure,
    residual_figure,
    spectrum_figure,
    validity_figure,
)
from torchpaml._render.report import write_report
from torchpaml._render.schema import SCHEMA_VERSION, diagnosis_to_dict, discovery_to_dict
from torchpaml._render.tables import comparison_table, ranking_table
from torchpaml._residual import AbstractResidual, ChebyshevHammerstein, ForceAugmented, MLPForce, MLPResidual
from torchpaml._signals import chirp, cosine, multisine, pseudorandom, sine, time_grid
from torchpaml._simulate import (
    RK4,
    TRBDF2,
    Auto,
    Dopri5,
    Exact,
    Solver,
    WarmStart,
    iir_filter,
    output_jacobian,
    simulate,
)

__all__ = [
    # physics and effects
    "AbstractPhysics",
    "SecondOrderPhysics",
    "Oscillator",
    "Pendulum",
    "state_vector",
    "complete_state",
    "AbstractEffect",
    "ComposedModel",
    "ConstantForce",
    "CoulombFriction",
    "CubicStiffness",
    "DeadZone",
    "Hysteresis",
    "DynamicFriction",
    "InputLag",
    "EffectState",
    "DiscoveredForce",
    "InputSaturation",
    "OutputSaturation",
    "PendulumRestoring",
    "QuadraticDamping",
    "QuadraticStiffness",
    "EFFECTS",
    "PHYSICS",
    "build_model",
    "TermLibrary",
    "SparseRegression",
    "default_effects",
    # parameters
    "Interval",
    "PhysicalParameter",
    "Positive",
    "Real",
    "register_parameters",
    # records and signals
    "Record",
    "RecordSource",
    "Files",
    "Simulated",
    "chirp",
    "cosine",
    "multisine",
    "pseudorandom",
    "sine",
    "time_grid",
    # simulation
    "simulate",
    "simulate_record",
    "Solver",
    "Auto",
    "Exact",
    "RK4",
    "TRBDF2",
    "Dopri5",
    "WarmStart",
    "output_jacobian",
    "iir_filter",
    # fitting
    "fit_physics",
    "PhysicsEstimate",
    "InitialState",
    "Rest",
    "Estimate",
    "Budget",
    "OverBudget",
    "Uncertainty",
    "IdentifiabilityWarning",
    "estimate_initial_state",
    "fit_chebyshev_hammerstein",
    "fit_residual",
    "ResidualEstimate",
    "fit_neural_force",
    "reestimate_shift",
    # residuals
    "AbstractResidual",
    "ChebyshevHammerstein",
    "MLPResidual",
    "MLPForce",
    "ForceAugmented",
    "Certificate",
    "incompatibility_certificates",
    # measures
    "mismatch",
    "channel_mismatch",
    "fit_percent",
    "rmse",
    # diagnostics
    "diagnose",
    "Diagnosis",
    "HybridScore",
    "hybrid_residual",
    "compare",
    "Comparison",
    "residual_analysis",
    "ResidualAnalysis",
    "error_by_amplitude",
    "AmplitudeBins",
    "validity_map",
    "ValidityMap",
    "harmonic_fingerprint",
    "HarmonicFingerprint",
    "assess_adequacy",
    "Adequacy",
    "rank_missing_effects",
    "Ranker",
    "SelectionRule",
    "Ranking",
    "EffectEvidence",
    "ModelScore",
    "model_ladder",
    "Ladder",
    "discover_missing_force",
    "Discoverer",
    "Discovery",
    # rendering
    "write_report",
    "diagnosis_to_dict",
    "discovery_to_dict",
    "SCHEMA_VERSION",
    "diagnosis_figures",
    "comparison_figure",
    "comparison_table",
    "ranking_figure",
    "ranking_table",
    "ladder_figure",
    "residual_analysis_figure",
    "amplitude_figure",
    "validity_figure",
    "discovery_figure",
    "overlay_figure",
    "residual_figure",
    "spectrum_figure",
    # Lightning
    "HybridSystem",
    "PhysicsFit",
    "ResidualFit",
    "JointFit",
    "RecordDataModule",
    # errors
    "ConfigurationError",
    "DataError",
    "DomainError",
    "ResolutionError",
    "SimulationError",
    "PhysicsError",
    "TorchpamlError",
]

#: Names whose module imports Lightning: loaded on first access, so that ``import torchpaml`` stays light.
_LIGHTNING = ("RecordDataModule", "ExperimentDataModule", "HybridSystem", "JointFit", "PhysicsFit", "ResidualFit")


def __getattr__(name: str):
    if name in _LIGHTNING:
        value = getattr(importlib.import_module("torchpaml._training"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'torchpaml' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
