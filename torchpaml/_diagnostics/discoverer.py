"""The discovery stage of a diagnosis: how a force outside the library is discovered, as one frozen value."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

from torchpaml._data import Record
from torchpaml._diagnostics.discovery import Discovery, discover_missing_force, library_best
from torchpaml._diagnostics.results import Ranking
from torchpaml._errors import ConfigurationError
from torchpaml._fit.sparse_regression import SparseRegression
from torchpaml._physics.terms import TermLibrary

__all__ = ["Discoverer"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Discoverer:
    """The settings of :func:`~torchpaml.discover_missing_force` (its module docstring has the method).

    Attributes:
        library: the terms to regress on (:class:`~torchpaml.TermLibrary`; ``TermLibrary(terms=[...])`` adds the
            user's own, sympy strings over the physics' variables).
        regression: the sparse regression (:class:`~torchpaml.SparseRegression`).
        max_iter: L-BFGS iterations of the neural rate.
        max_nfev: iteration limit of the closed form's refit.
        seed: seed of the network's initial weights.
        always: search even where the ladder's last rung is complete (its residual is noise that the orthogonal
            residual cannot reduce); by default the discovery then says so and stops (``--discover_always``).
    """

    library: TermLibrary = field(default_factory=TermLibrary)
    regression: SparseRegression = field(default_factory=SparseRegression)
    max_iter: int = 60
    max_nfev: int = 40
    seed: int = 0
    always: bool = False

    def __post_init__(self):
        for name in ("max_iter", "max_nfev"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ConfigurationError(f"{name} must be a whole number, at least 1; got {value!r}")

    def discover(self, ranking: Ranking, train: Sequence[Record], validation: Sequence[Record],
                 deadline: float | None = None, complete: bool = False) -> Discovery:
        """:func:`~torchpaml.discover_missing_force` on ``ranking`` (the ladder's last) with these settings; where
        the rung is ``complete`` (``Adequacy.complete``) and not :attr:`always`, a discovery that says so, without a
        search (``Discovery.searched`` false)."""
        if complete and not self.always:
            reason = (f"{ranking.baseline.name} is complete at this noise level (its residual is noise that the "
                      "orthogonal residual cannot reduce): nothing to discover; to search anyway, "
                      "Discoverer(always=True) or --discover_always")
            log.info("discovery: %s", reason)
            return Discovery(ranking.baseline, library_best(ranking), None, None, None, None, False, reason, {},
                             searched=False)
        return discover_missing_force(ranking, train, validation, library=self.library, regression=self.regression,
                                      max_iter=self.max_iter, max_nfev=self.max_nfev, seed=self.seed,
                                      deadline=deadline)
