r"""The one decision rule of the ranking, the ladder and discovery: is a candidate model better than the current one?

A :class:`SelectionRule` scores a fitted model on the validation records by an information criterion,

$$ \mathrm{BIC} = n \ln(\mathrm{SSE}/n) + k \ln n, \qquad \mathrm{AIC} = n\ln(\mathrm{SSE}/n) + 2k, $$

($k$ fitted parameters, $n$ samples) and accepts a candidate over the current model when

- its criterion is lower by more than ``threshold`` (10: very strong evidence on the Kass-Raftery scale);
- its validation mismatch is lower by at least the share ``min_share`` (5 %): on a long record whose
  residual is not white, a criterion gain alone accepts models that change nothing;
- its training mismatch is not above the current model's: a candidate that contains the current model
  (an effect at strength 0) and fits the training records worse is a failed optimisation, not evidence.
"""

from __future__ import annotations

from torchpaml._errors import ConfigurationError

import math
import sys
from dataclasses import dataclass
from typing import Literal

__all__ = ["SelectionRule"]

#: Relative slack of "not above the current training mismatch" (the optimiser's last digits).
TRAINING_SLACK = 1e-6


@dataclass(frozen=True)
class SelectionRule:
    """The decision rule (module docstring).

    Args:
        criterion: ``"bic"`` or ``"aic"``, on the validation records.
        threshold: criterion improvement needed to accept a candidate.
        min_share: relative fall of the validation mismatch needed to accept a candidate.
    """

    criterion: Literal["bic", "aic"] = "bic"
    threshold: float = 10.0
    min_share: float = 0.05

    def __post_init__(self):
        if self.criterion not in ("bic", "aic"):
            raise ConfigurationError(f"criterion must be 'bic' or 'aic', got {self.criterion!r}")
        if not 0 <= self.min_share < 1:
            raise ConfigurationError(f"min_share is a share of the validation mismatch, in [0, 1); got {self.min_share}")

    def value(self, sse: float, samples: int, parameters: int) -> float:
        """The criterion of a fit with sum of squared errors ``sse`` on ``samples`` samples and ``parameters`` fitted.

        A fit that reproduces the records exactly (``sse`` 0: noise-free records of the same model, simulated along
        the same arithmetic) counts the smallest positive float64 per sample in place of its error: the criterion
        stays finite, and between two exact fits the penalty decides."""
        return samples * math.log(max(sse / samples, sys.float_info.min)) + self.penalty(samples, parameters)

    def penalty(self, samples: int, parameters: int) -> float:
        """The criterion's charge for ``parameters`` unknowns on ``samples`` samples: $k \\ln n$ (BIC), $2k$ (AIC)."""
        return parameters * math.log(samples) if self.criterion == "bic" else 2.0 * parameters

    def why_not(self, current, candidate, extra: int = 0, nested: bool = True) -> str | None:
        """Why ``candidate`` is not accepted over ``current`` (both :class:`~torchpaml.ModelScore`),
        or ``None`` when it is. ``extra``: more unknowns the candidate has beyond its fitted parameters (an effect's
        own states), each charged as one more parameter in its criterion (``candidate.samples`` samples; fewer where
        negative). ``nested=False`` drops the training clause, for two models neither of which extends the other
        (the beam's ends): a lower training mismatch is then not owed."""
        if nested and candidate.nrmse_train > current.nrmse_train * (1 + TRAINING_SLACK):
            return "its refit ended above the current model's training mismatch (a failed optimisation)"
        charge = self.penalty(candidate.samples, extra) if extra and candidate.samples else 0.0
        gain = current.criterion - candidate.criterion - charge
        share = 1 - candidate.nrmse_validation / current.nrmse_validation
        if gain <= self.threshold or share < self.min_share:
            counted = f", {extra} own state(s) counted as parameters" if charge else ""
            return (f"it changes the criterion by {gain:+.1f}{counted} (needed more than {self.threshold:g}) and the "
                    f"validation mismatch by {100 * share:.1f} % (needed {100 * self.min_share:g} %)")
        return None

    def accepts(self, current, candidate, extra: int = 0, nested: bool = True) -> bool:
        """Whether ``candidate`` is better than ``current`` by this rule (``extra``, ``nested``: :meth:`why_not`)."""
        return self.why_not(current, candidate, extra, nested) is None
