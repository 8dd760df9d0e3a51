"""torchpaml: physics-augmented learning of input-driven dynamical systems, with orthogonal residuals.

Fit an ODE physics model to measurements u(t), y(t), see where it fails, find the physical effect it
misses, add it, and put a Chebyshev-Hammerstein residual on top that improves accuracy but cannot hide
wrong physics (Kuang & Lin, "Structural Constraints for Physics-augmented Learning").

The top level holds what a script writes: physics and effects, records and signals, solvers, the fits,
``diagnose`` and its stages, the residuals, the error measures, the report writer, the Lightning systems
and the errors. The rest lives in named modules: :mod:`torchpaml.analysis` (the analyses a diagnosis
composes), :mod:`torchpaml.figures`, :mod:`torchpaml.report` (JSON content and tables) and
:mod:`torchpaml.engine` (the simulation engine's pieces). The modules behind them are private. The command
line is ``torchpaml`` (:mod:`torchpaml.cli`). The Lightning systems load Lightning on first use.
"""

import importlib
import warnings

from torchpaml._budget import Budget, OverBudget
from torchpaml._data import Files, Record, RecordSource, Simulated, simulate_record
from torchpaml._data import Experiment, ExperimentSource  # noqa: F401  the earlier names of Record, RecordSource
from torchpaml._diagnostics import (
    Adequacy,
    Diagnosis,
    Discoverer,
    MismatchProbes,
    Prober,
    Discovery,
    EffectEvidence,
    HybridScore,
    Ladder,
    ModelScore,
    Ranker,
    Ranking,
    SelectionRule,
    diagnose,
)
from torchpaml._errors import (
    CompiledPathWarning,
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
    FittedModel,
    InitialState,
    PhysicsEstimate,
    ResidualEstimate,
    Rest,
    SparseRegression,
    estimate_initial_state,
    fit_chebyshev_hammerstein,
    fit_neural_force,
    fit_physics,
    fit_residual,
    reestimate_shift,
)
from torchpaml._fit.uncertainty import IdentifiabilityWarning, Uncertainty
from torchpaml._metrics import channel_mismatch, fit_percent, mismatch, rmse
from torchpaml._parameters import Interval, PhysicalParameter, Positive, Real, register_parameters
from torchpaml._physics import (
    EFFECTS,
    AbstractEffect,
    AbstractPhysics,
    ComposedModel,
    DiscoveredForce,
    EffectState,
    Oscillator,
    Pendulum,
    SecondOrderPhysics,
    TermLibrary,
    default_effects,
    state_vector,
)
from torchpaml._physics import effects as _effects
from torchpaml._physics.effects import *  # noqa: F403  the library's effects (EFFECT_CLASSES, derived from EFFECTS)
from torchpaml._physics.registry import PHYSICS, build_model
from torchpaml._render.report import write_report
from torchpaml._export import export_model
from torchpaml._track import Tracker, track
from torchpaml._model import Prediction, load_model, predict, save_model
from torchpaml._residual import AbstractResidual, ChebyshevHammerstein, ForceAugmented, MLPForce, MLPResidual
from torchpaml._signals import chirp, cosine, multisine, pseudorandom, sine, time_grid
from torchpaml._simulate import RK4, TRBDF2, Auto, Dopri5, Exact, Solver, simulate
from torchpaml._simulate.solvers import FixedStep
from torchpaml import analysis, engine, figures, report  # noqa: E402  the named modules, as tp.figures, ...

__all__ = [
    # physics and effects (the library's effects: EFFECT_CLASSES)
    "AbstractPhysics", "SecondOrderPhysics", "Oscillator", "Pendulum", "state_vector", "AbstractEffect",
    "ComposedModel", "EffectState", "DiscoveredForce", "EFFECTS", "default_effects", "PHYSICS", "build_model",
    "TermLibrary", "SparseRegression", *_effects.EFFECT_CLASSES,
    # parameters
    "Interval", "PhysicalParameter", "Positive", "Real", "register_parameters",
    # records and signals
    "Record", "RecordSource", "Files", "Simulated", "chirp", "cosine", "multisine", "pseudorandom", "sine",
    "time_grid",
    # simulation
    "simulate", "simulate_record", "Solver", "FixedStep", "Auto", "Exact", "RK4", "TRBDF2", "Dopri5",
    # fitting
    "fit_physics", "PhysicsEstimate", "FittedModel", "InitialState", "Rest", "Estimate", "Budget", "OverBudget", "Uncertainty",
    "IdentifiabilityWarning", "estimate_initial_state", "fit_chebyshev_hammerstein", "fit_residual",
    "ResidualEstimate", "fit_neural_force", "reestimate_shift",
    # a fitted model at work: its file and its predictions
    "save_model", "load_model", "predict", "Prediction", "export_model", "track", "Tracker",
    # residuals
    "AbstractResidual", "ChebyshevHammerstein", "MLPResidual", "MLPForce", "ForceAugmented",
    # measures
    "mismatch", "channel_mismatch", "fit_percent", "rmse",
    # the diagnosis and its stages
    "diagnose", "Diagnosis", "Ranker", "Discoverer", "SelectionRule", "Ranking", "EffectEvidence", "ModelScore",
    "Ladder", "Discovery", "Adequacy", "HybridScore", "Prober", "MismatchProbes", "write_report",
    # Lightning
    "HybridSystem", "PhysicsFit", "ResidualFit", "JointFit", "RecordDataModule",
    # errors
    "ConfigurationError", "DataError", "DomainError", "ResolutionError", "SimulationError", "PhysicsError",
    "TorchpamlError", "CompiledPathWarning",
]

#: Names whose module imports Lightning: loaded on first access, so that ``import torchpaml`` stays light.
_LIGHTNING = ("RecordDataModule", "ExperimentDataModule", "HybridSystem", "JointFit", "PhysicsFit", "ResidualFit")
#: Names that moved from the top level to a named module (CHANGELOG, Deprecated): still found here, with a
#: DeprecationWarning, until the next release.
_MOVED = {
    **dict.fromkeys(figures.__all__, "torchpaml.figures"),
    **dict.fromkeys(["SCHEMA_VERSION", "comparison_table", "diagnosis_to_dict", "discovery_to_dict",
                     "ranking_table"], "torchpaml.report"),
    **dict.fromkeys(["WarmStart", "complete_state", "iir_filter", "output_jacobian"], "torchpaml.engine"),
    **dict.fromkeys(analysis.__all__, "torchpaml.analysis"),
}


def __getattr__(name: str):
    if name in _LIGHTNING:
        value = getattr(importlib.import_module("torchpaml._training"), name)
        globals()[name] = value
        return value
    if name in _MOVED:
        warnings.warn(f"torchpaml.{name} moved to {_MOVED[name]}.{name}; the top-level name goes in the next "
                      "release", DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(_MOVED[name]), name)
    raise AttributeError(f"module 'torchpaml' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
