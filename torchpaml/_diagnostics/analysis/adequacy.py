r"""The inadequacy alarm: when the orthogonal residual cannot close the gap, say so.

The Chebyshev-Hammerstein residual is orthogonal to the physics output and to its sensitivities,
so it cannot absorb an error the physics should fix. If the physics is adequate, the hybrid
removes most of what is left: $m_{\text{hybrid}} \le \kappa\, m_{\text{physics}}$ on the training
record, and it also beats the physics on validation. The alarm goes off when either fails:
- the hybrid's training mismatch stays above $\kappa$ (default 0.5) times the physics';
- or its validation mismatch is no better than the physics'.
The physics is then inadequate in this regime, and the hybrid's number must not be quoted as
a model's accuracy. The exception is a physics whose residual is noise, by effect size: linearly
uncorrelated with the input (``residual_white``; :func:`~torchpaml.diagnose` decides it
from :func:`~torchpaml.residual_analysis`; coloured sensor noise counts as noise), beyond the reach of the
orthogonal residual, which sees odd nonlinear functions of the input too
($m_{\text{hybrid}} > $ :data:`NOISE_RATIO` $\, m_{\text{physics}}$ on training), *and* at the noise floor on
validation: $m_{\text{physics}} \le$ :data:`FLOOR_FACTOR` times the floor read from the records
(:func:`~torchpaml._diagnostics.analysis.noise_floor.noise_floor`, a fraction of the validation records' RMS).
Noise that is not white reads low by differences; so where the training residual, noise, is itself above
:data:`FLOOR_FACTOR` times that floor, the training mismatch is the floor the validation mismatch must stay within
:data:`FLOOR_FACTOR` of (right physics under coloured sensor noise: 2.00 % on both records, against 0.55 % read by
differences, ``tests/diagnosis/test_long_record.py``). A stand-in that fits the training record through its own
states shows there: its validation mismatch rises above its training one.
Then there is no gap to close, and the verdict says that the physics is complete at that noise level. A training
residual that looks like noise while validation stays above the floor is not complete: a fitted effect may stand in
for the missing one on the training record (a memory effect for a cubic damping), and the verdict says how far
above the floor the physics is. A residual that the
hybrid does reduce (a missing friction is odd in the input and shows no linear correlation) is not
noise, whatever its linear correlation.

**A limit of the alarm.** The residual is a filter of the input's Chebyshev terms, so a missing effect that
is itself a filter on the input (an actuator lag, a sensor's own dynamics) lies within its reach: the hybrid
is then "adequate" while the physics alone stays far off. What gives it away is the physics' residual: a
missing static effect leaves it linearly uncorrelated with the input (the fitted linear dynamics already
take the best linear approximation), a missing linear dynamic effect does not, since the physics' own
parameters cannot make its phase. So when the hybrid is adequate and a linear filter of the input explains at
least :data:`LINEAR_SHARE` of the physics' training residual (``linear_share``, from
:func:`~torchpaml.residual_analysis`), the verdict says so (``covering``): the residual may be
covering a missing dynamic effect, which the physics should carry (the ``input_lag`` effect tests the commonest).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Adequacy", "FLOOR_FACTOR", "LINEAR_SHARE", "NOISE_RATIO", "assess_adequacy", "times"]

#: A residual linearly uncorrelated with the input is noise when the orthogonal residual removes less than
#: 10 % of the training mismatch (the hybrid's is above this share of the physics').
NOISE_RATIO = 0.9
#: The most a complete physics' validation mismatch may be, in multiples of the noise floor read from the records.
FLOOR_FACTOR = 1.2
#: The share of the physics' residual variance that a linear filter of the input explains above which an adequate
#: hybrid may be covering a missing dynamic effect (module docstring). Measured on the linear oscillator's residual,
#: 600-sample multisine records of the hidden-effect cases (``tests/diagnosis/test_hidden_effects.py``): 0.63 for a
#: lag of 6 samples, 0.44 for Bouc-Wen hysteresis (itself an effect with memory), at most 0.22 for the static ones.
LINEAR_SHARE = 0.5


@dataclass(frozen=True)
class Adequacy:
    """The verdict, the ratios it rests on, and a sentence for reports. ``covering``: adequate, but a linear filter
    of the input explains most of the physics' residual, the mark of a missing dynamic effect (module docstring);
    ``complete``: the physics' residual is noise that the orthogonal residual cannot reduce, at the validation
    records' noise floor (physics complete at this noise level); ``noise_floor``: that floor, a fraction (``None``:
    not measured)."""

    inadequate: bool
    train_ratio: float
    validation_ratio: float | None
    message: str
    covering: bool = False
    complete: bool = False
    noise_floor: float | None = None

    @property
    def recommends_hybrid(self) -> bool:
        """Whether the physics plus the residual is the model to use: neither inadequate physics (the residual would
        hide it) nor complete physics (its residual is noise; a residual fitted to it scores by chance)."""
        return not self.inadequate and not self.complete


def assess_adequacy(
    physics_train: float,
    hybrid_train: float,
    physics_validation: float | None = None,
    hybrid_validation: float | None = None,
    closes: float = 0.5,
    residual_white: bool = False,
    linear_share: float | None = None,
    noise_floor: float | None = None,
) -> Adequacy:
    """Mismatches as fractions (module docstring); ``closes`` is κ. ``residual_white``: the physics' training
    residual is linearly uncorrelated with the input; ``linear_share``: the share of its variance that a linear
    filter of the input explains (``None``: not measured); ``noise_floor``: the records' noise floor, a fraction
    of the validation records' RMS (``None``: not measured, and the floor does not enter the verdict)."""
    train_ratio = hybrid_train / physics_train
    validation_ratio = None if physics_validation is None else hybrid_validation / physics_validation
    above = None if noise_floor is None or physics_validation is None else \
        physics_validation / max(noise_floor, 1e-300)
    floor = "" if above is None else (f"; on validation {100 * physics_validation:.2f} %, "
                                      f"{times(above)} the noise floor read from the records "
                                      f"({100 * noise_floor:.2f} %)")
    noise = residual_white and train_ratio > NOISE_RATIO
    coloured = noise and above is not None and physics_train > FLOOR_FACTOR * noise_floor and \
        physics_validation <= FLOOR_FACTOR * physics_train
    if coloured:
        floor += (f", which its training residual, noise at {100 * physics_train:.2f} %, shows to read low (noise that "
                  f"is not white reads low by differences); on validation {times(physics_validation / physics_train)} "
                  "its training mismatch, within the same factor")
    if noise and (above is None or above <= FLOOR_FACTOR or coloured):
        return Adequacy(False, train_ratio, validation_ratio, (
            "physics complete at this noise level: its training residual is uncorrelated with the input (noise, "
            f"white or coloured), and the orthogonal residual has nothing to add ({100 * physics_train:.1f} % -> "
            f"{100 * hybrid_train:.1f} % on training){floor}; use the physics alone"), complete=True,
            noise_floor=noise_floor)
    reasons = []
    if noise:
        reasons.append(
            f"its training residual looks like noise, but on validation it is {times(above)} the noise floor read "
            f"from the records ({100 * physics_validation:.2f} % against {100 * noise_floor:.2f} %): an "
            "effect is missing, or a fitted effect stands in for it on the training record")
    if train_ratio > closes:
        reasons.append(
            f"the orthogonal residual closes only {100 * (1 - train_ratio):.0f} % of the physics' training error "
            f"({100 * physics_train:.1f} % -> {100 * hybrid_train:.1f} %)"
        )
    if validation_ratio is not None and validation_ratio >= 1:
        reasons.append(
            f"on validation the hybrid ({100 * hybrid_validation:.1f} %) is no better than the physics "
            f"({100 * physics_validation:.1f} %)"
        )
    if reasons:
        message = ("PHYSICS INADEQUATE in this regime: " + "; ".join(reasons) + ("" if noise else floor) +
                   ". Fix the physics (a missing effect, a wrong structure) before quoting the hybrid's accuracy.")
        return Adequacy(True, train_ratio, validation_ratio, message, noise_floor=noise_floor)
    message = (f"physics adequate: the orthogonal residual takes the training mismatch from "
               f"{100 * physics_train:.1f} % to {100 * hybrid_train:.1f} %{floor}")
    covering = linear_share is not None and linear_share >= LINEAR_SHARE
    if covering:
        message += (f"; but a linear filter of the input explains {100 * linear_share:.0f} % of the physics' residual, "
                    "which a missing static effect does not do: the residual, itself a filter of the input, may be "
                    "covering a missing dynamic effect (an actuator lag, a sensor's dynamics) that the physics should "
                    "carry; rank the input_lag effect, or add the dynamics to the physics")
    return Adequacy(False, train_ratio, validation_ratio, message, covering, noise_floor=noise_floor)


def times(ratio: float) -> str:
    """A ratio to the noise floor in words, to the hundredth below 10 (the 1.2 of the adequacy test reads apart from
    1.19 and 1.15): ``0.44 times``, ``1.04 times``, ``13 times``, ``240 times``, ``more than 1000 times``."""
    if ratio > 1000:
        return "more than 1000 times"
    return f"{ratio:.2g} times" if ratio < 0.1 else f"{ratio:.2f} times" if ratio < 10 else f"{ratio:.0f} times"
