r"""What limits a benchmark's figure: one rule over the measured numbers, which writes the label and its sentence.

With $e$ the final grey box's error on the headline split, $f$ the output noise's RMS where the benchmark measures
it on repeats of its input (same unit; else the diagnosis' own verdict stands in), $\kappa$ =
:data:`~torchpaml._diagnostics.analysis.adequacy.FLOOR_FACTOR` (1.2) and $e_r$ the error with the input-driven
(Chebyshev-Hammerstein) residual fitted on the training records:

- at the floor: $e \le \kappa f$; without $f$, the diagnosis calls the final grey box complete (its validation
  mismatch within $\kappa$ times the floor it reads from the records, its training residual noise);
- an input response left: $e_r < (1 -$ :data:`MIN_REMOVED` $) e$.

| at the floor | an input response left | limit |
|---|---|---|
| yes | no | ``"noise floor"`` |
| no | either | ``"model class"`` (with the share the residual removes and the place the probes name) |
| yes | yes | ``"undetermined"``: the noise test and the residual disagree |

Every number the rule reads goes into ``evidence`` (``complete``: the diagnosis' verdict); the sentence states them
and nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass

from torchpaml._diagnostics.analysis.adequacy import FLOOR_FACTOR, Adequacy, times

__all__ = ["LIMITS", "MIN_REMOVED", "LimitFigures", "limit_of"]

#: What may limit a figure (the rule's three outcomes, module docstring).
LIMITS = ("noise floor", "model class", "undetermined")
#: The share of the final error an input-driven residual must remove on the headline split to count as a response
#: to the input that the grey box does not express.
MIN_REMOVED = 0.05


@dataclass(frozen=True)
class LimitFigures:
    """The measured numbers the rule reads.

    Attributes:
        error: the final grey box's error on the headline split (the benchmark's unit).
        unit: that unit.
        adequacy: the diagnosis' verdict on the final rung (its ``complete`` and ``noise_floor``).
        validation: the final grey box's validation mismatch, a fraction (NRMSE).
        floor: the output noise's RMS read on repeats of the input, in ``unit`` (``None``: not measured).
        with_residual: the headline split's error with the input-driven residual (``None``: not scored, e.g. a test
            input beyond its domain).
        probe: the place the probes name, as ``(place, fitted, validation gain)`` (``None``: none named).
    """

    error: float
    unit: str
    adequacy: Adequacy
    validation: float
    floor: float | None = None
    with_residual: float | None = None
    probe: tuple[str, str, float] | None = None


def limit_of(figures: LimitFigures) -> tuple[str, dict[str, float], str]:
    """The limit (one of :data:`LIMITS`), the evidence it rests on and the sentence that states it (module
    docstring)."""
    e, unit, adequacy = figures.error, figures.unit, figures.adequacy
    evidence = {"final": e, "validation_nrmse": figures.validation, "complete": adequacy.complete}
    if adequacy.noise_floor is not None:
        evidence["diagnosis_noise_floor_nrmse"] = adequacy.noise_floor
    diagnosis = (f"the diagnosis {'calls' if adequacy.complete else 'does not call'} the final grey box complete "
                 f"(validation mismatch {100 * figures.validation:.3g} %"
                 + ("" if adequacy.noise_floor is None else
                    f", {times(figures.validation / max(adequacy.noise_floor, 1e-300))} the noise floor it reads "
                    f"from the records, {100 * adequacy.noise_floor:.3g} %") + ")")
    if figures.floor is not None:
        evidence |= {"noise_floor": figures.floor, "final_over_noise_floor": e / figures.floor}
        at_floor = e <= FLOOR_FACTOR * figures.floor
        floor = (f"the final grey box's error ({e:.3g} {unit}) is {e / figures.floor:.2f} times the output noise "
                 f"read on the input's repeats ({figures.floor:.3g} {unit}; at the floor: at most {FLOOR_FACTOR:g} "
                 f"times); {diagnosis}")
    else:
        at_floor = adequacy.complete
        floor = f"{diagnosis}; the final grey box's error is {e:.3g} {unit}"
    responds = False
    if figures.with_residual is not None:
        evidence["with_input_residual"] = figures.with_residual
        removed = 1 - figures.with_residual / e
        responds = removed >= MIN_REMOVED
        change = f"removes {100 * removed:.3g} % of it" if removed >= 0 else \
            f"removes none of it (it grows by {-100 * removed:.3g} %)"
        floor += (f"; an input-driven residual (the Chebyshev-Hammerstein model, fitted on training) {change} "
                  f"({figures.with_residual:.3g} {unit}; a response to the input: at least {100 * MIN_REMOVED:g} % "
                  f"removed)")
    if figures.probe is not None:
        place, fitted, gain = figures.probe
        evidence["probe_gain"] = gain
        floor += f"; the probes point at the {place} ({fitted}, a validation gain of {100 * gain:.3g} %)"
    if at_floor and not responds:
        return "noise floor", evidence, f"the noise floor: {floor}"
    if at_floor:
        return "undetermined", evidence, (f"undetermined: the error is at the noise floor, yet a response to the input "
                                          f"is left: {floor}")
    return "model class", evidence, f"the model class: {floor}"
