"""The JSON contracts: ``diagnosis.json`` and ``discovery.json`` as plain dicts of a diagnosis' result objects.

Mismatches are fractions, $\\|y - \\hat y\\| / \\|y\\|$. Every field is documented on the reference page
``docs/reference/outputs.md``; :data:`SCHEMA_VERSION` names the version of that layout and is the
first field of both files. It grows when a field is renamed or removed (adding a field keeps it).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from torchpaml._diagnostics.ranking.occam import KINDS, kind

if TYPE_CHECKING:
    from torchpaml._diagnostics import (AmplitudeBins, Diagnosis, Discovery, EffectEvidence, HybridScore, Ladder,
                                        MismatchProbes)

__all__ = ["SCHEMA_VERSION", "diagnosis_to_dict", "discovery_to_dict"]

#: The version of the ``diagnosis.json`` / ``discovery.json`` layout.
SCHEMA_VERSION = 1


def evidence_to_dict(evidence: EffectEvidence) -> dict:
    """One row of ``ranking``: a candidate's score and, where refitted, its refitted model's errors."""
    refit = evidence.refit
    return {
        "effect": evidence.effect, "equation": evidence.equation, "score": evidence.score, "order": evidence.order,
        "first_order_strength": evidence.first_order_strength, "refitted": refit is not None,
        "nrmse_train": None if refit is None else refit.nrmse_train,
        "nrmse_validation": None if refit is None else refit.nrmse_validation,
        "criterion": None if refit is None else refit.criterion,
        "improvement": evidence.improvement, "parameters": {} if refit is None else refit.parameters,
        "uncertainty": {} if refit is None else _errors(refit.uncertainty), "unphysical": evidence.unphysical,
        "failure": evidence.failure, "refit_reason": evidence.refit_reason, "undecided": evidence.undecided,
        "acting": evidence.acting, "kind": KINDS[kind(evidence)],
    }


def ladder_to_dicts(ladder: Ladder) -> list[dict]:
    """One dict per rung of the ladder (``solver``: the method the rung was fitted and scored with, ``"Exact"``,
    ``"RK4"`` or ``"TRBDF2"``; ``substeps``: its steps per sample interval, 1 on the exact path; ``fit_over_budget``:
    the seconds after which its fit stopped over its budget, the rung keeping its refit's parameters, else null;
    ``simpler``: how the simpler-effect rule weighed the added effect against the other kinds the rule accepted,
    :mod:`~torchpaml._diagnostics.ranking.occam`, else null; ``equivalent``: the candidates that give the added
    effect's evidence on this physics, which the records cannot tell from it; ``removed``: the earlier effect taken
    out of the rung's model as a stand-in, :mod:`~torchpaml._diagnostics.ranking.removal`, else null)."""
    return [
        {"model": s.name, "equation": s.equation, "added": None if i == 0 else ladder.added[i - 1],
         "removed": None if i == 0 or i > len(ladder.removed) else ladder.removed[i - 1],
         "nrmse_train": s.nrmse_train, "nrmse_validation": s.nrmse_validation, "criterion": s.criterion,
         "parameters": s.parameters, "uncertainty": _errors(s.uncertainty), "identifiability": s.warning,
         "fit_over_budget": ladder.rankings[i].fit_over_budget if i < len(ladder.rankings) else None,
         "simpler": None if i == 0 else ladder.rankings[i - 1].simpler,
         "equivalent": [] if i == 0 else ladder.rankings[i - 1].equivalent, **_solver(s.solver)}
        for i, s in enumerate(ladder.steps)
    ]


def _solver(solver) -> dict:
    """``{solver, substeps}`` of a rung's model: ``{"Auto", None}`` for a model that no fit resolved."""
    return {"solver": type(solver).__name__, "substeps": solver.substeps}


def hybrid_to_dict(hybrid: HybridScore) -> dict:
    """One row of ``hybrid``: a rung with the Chebyshev residual on top, and the inadequacy alarm's verdict."""
    return {"model": hybrid.model, "nrmse_train": hybrid.hybrid_train, "nrmse_validation": hybrid.hybrid_validation,
            "physics_nrmse_train": hybrid.physics_train, "physics_nrmse_validation": hybrid.physics_validation,
            "inadequate": hybrid.adequacy.inadequate, "covering": hybrid.adequacy.covering,
            "complete": hybrid.adequacy.complete, "noise_floor": hybrid.adequacy.noise_floor,
            "message": hybrid.adequacy.message}


def _error(std: float) -> float | None:
    """A standard error as written: ``None`` (JSON ``null``) where the records do not determine the parameter
    (an infinite or undefined error), so that no file carries ``Infinity``."""
    return std if math.isfinite(std) else None


def _errors(uncertainty: dict[str, float]) -> dict[str, float | None]:
    return {name: _error(std) for name, std in uncertainty.items()}


def _terms(discovery: Discovery) -> list[dict]:
    """``[{term, coefficient, std, equation}]``: each discovered term, its coefficient in the rate (gain included)
    and that coefficient's standard error."""
    if discovery.effect is None:
        return []
    effect = discovery.effect
    errors = effect.coefficient_errors(discovery.discovered.uncertainty)
    return [{"term": term, "coefficient": c, "std": _error(std), "equation": e}
            for (term, c, e), std in zip(effect.terms_and_coefficients(), errors, strict=True)]


def discovery_to_dict(discovery: Discovery) -> dict:
    """The content of ``discovery.json``."""
    library = None if discovery.library_best is None else discovery.library_best.refit
    final = discovery.discovered or discovery.physics
    return {
        "schema_version": SCHEMA_VERSION,
        "expression": discovery.expression,
        "terms": _terms(discovery),
        "recommended": discovery.recommended,
        "nrmse_validation": {"physics": discovery.physics.nrmse_validation,
                             "library_best": None if library is None else library.nrmse_validation,
                             "neural": discovery.neural_validation, "discovered": final.nrmse_validation},
        "library_best": None if discovery.library_best is None else discovery.library_best.effect,
        "reason": discovery.reason,
        "nrmse_train": {"physics": discovery.physics.nrmse_train,
                        "library_best": None if library is None else library.nrmse_train,
                        "neural": discovery.neural_train, "discovered": final.nrmse_train},
        "criterion": {"physics": discovery.physics.criterion,
                      "library_best": None if library is None else library.criterion,
                      "discovered": final.criterion},
        "parameters": final.parameters,
        "uncertainty": _errors(final.uncertainty),
        "effect": None if discovery.effect is None else discovery.effect.to_config(),
        "undecided": discovery.undecided,
        "searched": discovery.searched,
        "replaces": discovery.replaces,
    }


def probes_to_dict(probes: MismatchProbes | None) -> dict | None:
    """The ``where_the_mismatch_points`` entry of ``diagnosis.json`` (``None`` where no probe was asked for)."""
    if probes is None:
        return None
    best = probes.best
    return {
        "model": probes.model,
        "nrmse_validation": probes.validation,
        "best": None if best is None else best.place,
        "min_gain": probes.min_gain,
        "reason": probes.reason or None,
        "in_time": None if probes.in_time is None else {"start_share": probes.in_time.start_share,
                                                        "growth": probes.in_time.growth,
                                                        "description": probes.in_time.describe()},
        "probes": [{"place": r.place, "extension": r.extension, "fitted": r.fitted, "nrmse_validation": r.validation,
                    "gain": r.gain, "note": r.note,
                    "parameters": None if r.score is None else r.score.parameters} for r in probes.rows],
    }


def _bins(bins: AmplitudeBins) -> dict:
    return {"edges": bins.edges.tolist(), "counts": bins.counts.tolist(),
            "nrmse": [float(m) if math.isfinite(m) else None for m in bins.mismatch]}


def diagnosis_to_dict(diagnosis: Diagnosis) -> dict:
    """The content of ``diagnosis.json``."""
    base, ranking = diagnosis.baseline, diagnosis.ranking
    return {
        "schema_version": SCHEMA_VERSION,
        "baseline": {"model": base.name, "equation": base.equation, "nrmse_train": base.nrmse_train,
                     "nrmse_validation": base.nrmse_validation, "criterion": base.criterion,
                     "parameters": base.parameters, "uncertainty": _errors(base.uncertainty),
                     "identifiability": base.warning},
        "ranking": [evidence_to_dict(e) for e in ranking.entries],
        "skipped_candidates": ranking.skipped,
        "criterion": {"name": ranking.rule.criterion, "threshold": ranking.rule.threshold,
                      "min_share": ranking.rule.min_share},
        "ladder": ladder_to_dicts(diagnosis.ladder),
        "removals": [{"rung": r.rung, "effect": r.effect, "nrmse_validation": r.nrmse_validation,
                      "criterion": r.criterion, "removed": r.removed, "reason": r.reason}
                     for r in diagnosis.ladder.removals],
        "beam": [{"effects": list(end.effects), "nrmse_validation": end.nrmse_validation, "criterion": end.criterion,
                  "greedy": end.greedy, "chosen": end.chosen, "ended": end.ended, "reason": end.reason}
                 for end in diagnosis.ladder.beam],
        "undecided": [{"model": ranking.baseline.name, "effect": e.effect, "seconds": e.undecided,
                       "reason": e.refit_reason} for ranking in diagnosis.ladder.rankings for e in ranking.undecided],
        "where_it_fails": {
            "residual_autocorrelation_lags_outside": diagnosis.residuals.autocorrelation_outside.tolist(),
            "input_cross_correlation_lags_outside": diagnosis.residuals.cross_correlation_outside.tolist(),
            "confidence": diagnosis.residuals.confidence,
            "by_input_amplitude": _bins(diagnosis.by_input),
            "by_output_amplitude": _bins(diagnosis.by_output),
            "channels": [{"name": c.name, "nrmse_validation_physics": c.physics, "nrmse_validation_final": c.final,
                          "rmse_validation_physics": c.rmse_physics, "rmse_validation_final": c.rmse_final,
                          "input_cross_correlation_lags_outside": c.residuals.cross_correlation_outside.tolist(),
                          "by_input_amplitude": _bins(c.by_input), "by_output_amplitude": _bins(c.by_output)}
                         for c in diagnosis.channels],
            "shows_most": diagnosis.shows_most.name,
        },
        "hybrid": [hybrid_to_dict(h) for h in diagnosis.hybrids],
        "discovery": None if diagnosis.discovery is None else discovery_to_dict(diagnosis.discovery),
        "where_the_mismatch_points": probes_to_dict(diagnosis.probes),
        "verdict": diagnosis.verdict,
    }
