r"""The inadequacy alarm: when the orthogonal residual cannot close the gap, say so.

The Chebyshev-Hammerstein residual is orthogonal to the physics output and to its sensitivities,
so it cannot absorb an error the physics should fix. If the physics is adequate, the hybrid
removes most of what is left: $m_{\text{hybrid}} \le \kappa\, m_{\text{physics}}$ on the training
record, and it also beats the physics on validation. The alarm goes off when either fails:
- the hybrid's training mismatch stays above $\kappa$ (default 0.5) times the physics';
- or its validation mismatch is no better than the physics'.
The physics is then inadequate in this regime, and the hybrid's number must not be quoted as
a model's accuracy. The exception is a physics whose residual is noise, by effect size: linearly
uncorrelated with the input (``residual_white``; :func:`~torchpaml._diagnostics.diagnose` decides it
from :func:`~torchpaml._diagnostics.residual_analysis`; coloured sensor noise counts as noise), *and*
beyond the reach of the orthogonal residual, which sees odd nonlinear functions of the input too
($m_{\text{hybrid}} > $ :data:`NOISE_RATIO` $\, m_{\text{physics}}$ on training). Then there is no gap
to close, and the verdict says that the physics is complete at that noise level. A residual that the
hybrid does reduce (a missing friction is odd in the input and shows no linear correlation) is not
noise, whatever its linear correlation.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Adequacy", "NOISE_RATIO", "assess_adequacy"]

#: A residual linearly uncorrelated with the input is noise when the orthogonal residual removes less than
#: 10 % of the training mismatch (the hybrid's is above this share of the physics').
NOISE_RATIO = 0.9


@dataclass(frozen=True)
class Adequacy:
    """The verdict, the ratios it rests on, and a sentence for reports."""

    inadequate: bool
    train_ratio: float
    validation_ratio: float | None
    message: str


def assess_adequacy(
    physics_train: float,
    hybrid_train: float,
    physics_validation: float | None = None,
    hybrid_validation: float | None = None,
    closes: float = 0.5,
    residual_white: bool = False,
) -> Adequacy:
    """Mismatches as fractions (module docstring); ``closes`` is κ."""
    train_ratio = hybrid_train / physics_train
    validation_ratio = None if physics_validation is None else hybrid_validation / physics_validation
    if residual_white and train_ratio > NOISE_RATIO:
        return Adequacy(False, train_ratio, validation_ratio, (
            "physics complete at this noise level: its training residual is uncorrelated with the input (noise, "
            f"white or coloured), and the orthogonal residual has nothing to add ({100 * physics_train:.1f} % -> "
            f"{100 * hybrid_train:.1f} % on training); use the physics alone"))
    reasons = []
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
        message = ("PHYSICS INADEQUATE in this regime: " + "; ".join(reasons) + ". Fix the physics (a missing "
                   "effect, a wrong structure) before quoting the hybrid's accuracy.")
    else:
        message = (f"physics adequate: the orthogonal residual takes the training mismatch from "
                   f"{100 * physics_train:.1f} % to {100 * hybrid_train:.1f} %")
    return Adequacy(bool(reasons), train_ratio, validation_ratio, message)
