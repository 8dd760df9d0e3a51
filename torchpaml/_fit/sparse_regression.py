r"""Sparse regression: which few columns of a library explain a target, chosen by BIC.

For $b \approx A\xi$ with the columns of $A$ (samples, terms) scaled to unit norm:

* :func:`stlsq`: sequentially thresholded least squares (SINDy; Brunton, Proctor & Kutz 2016):
  solve least squares on the active columns, drop those with $|\xi_i| < \lambda\|b\|$, repeat until
  the active set stops changing. With unit columns, $|\xi_i|$ is the size of the term's contribution.
* :func:`forward_selection`: add, one at a time, the column that lowers the residual most.
* :class:`SparseRegression` (:meth:`~SparseRegression.select`): the candidate supports of both
  (STLSQ over a grid of $\lambda$ on each target given, the forward path's prefixes), each with at
  most ``max_terms`` columns whose coefficients the data determine (t-statistic at least ``min_t``),
  scored against the *measured* target, whose residual is noise, by the extended BIC of Chen & Chen
  (2008), $\mathrm{EBIC} = n\ln(\mathrm{SSE}/n) + k\ln n + 2\ln\binom{p}{k}$ for $k$ of $p$ columns;
  the lowest wins, the empty support included. The last term pays for the search: among tens of
  candidates the best one fits noise better than BIC's $\ln n$ alone allows for (plain BIC picks a
  spurious $u^2$ on records of the physics alone).

Plain least squares (``torch.linalg.lstsq``) does the work: the problems are tens of columns, so
PySINDy would add a dependency for a loop of ten lines.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import torch

__all__ = ["SparseRegression", "forward_selection", "stlsq"]

#: Thresholds $\lambda$ (shares of $\|b\|$) that :class:`SparseRegression` sweeps.
THRESHOLDS = (0.02, 0.05, 0.1, 0.2, 0.3, 0.4, 0.6, 0.8)


def _solve(A: torch.Tensor, b: torch.Tensor, support: Sequence[int]) -> tuple[torch.Tensor, float]:
    """Least-squares coefficients on ``support`` and the sum of squared residuals."""
    if not support:
        return torch.zeros(0, dtype=b.dtype), float(b @ b)
    columns = A[:, list(support)]
    xi = torch.linalg.lstsq(columns, b[:, None]).solution[:, 0]
    residual = b - columns @ xi
    return xi, float(residual @ residual)


def stlsq(A: torch.Tensor, b: torch.Tensor, threshold: float, max_iter: int = 30) -> list[int]:
    """STLSQ (module docstring) on unit columns A (samples, terms), b (samples,); returns the support."""
    active = list(range(A.shape[1]))
    for _ in range(max_iter):
        xi, _ = _solve(A, b, active)
        kept = [i for i, c in zip(active, xi.tolist(), strict=True) if abs(c) >= threshold * float(b.norm())]
        if kept == active:
            break
        active = kept
    return active


def forward_selection(A: torch.Tensor, b: torch.Tensor, max_terms: int) -> list[list[int]]:
    """The greedy path: ``[[i1], [i1, i2], ...]``, each step adding the column that lowers the SSE most."""
    chosen, path = [], []
    for _ in range(min(max_terms, A.shape[1])):
        remaining = [j for j in range(A.shape[1]) if j not in chosen]
        best = min(remaining, key=lambda j: _solve(A, b, chosen + [j])[1])
        chosen = chosen + [best]
        path.append(sorted(chosen))
    return path


def extended_bic(sse: float, samples: int, terms: int, columns: int) -> float:
    """$n\\ln(\\mathrm{SSE}/n) + k\\ln n + 2\\ln\\binom{p}{k}$ (module docstring)."""
    return (samples * math.log(max(sse, 1e-300) / samples) + terms * math.log(samples)
            + 2 * math.log(math.comb(columns, terms)))


def _t_statistic(A: torch.Tensor, b: torch.Tensor, support: Sequence[int]) -> float:
    """The smallest $|\\xi_i|/\\sigma_i$ of the least-squares fit on ``support`` (``inf`` for the empty support)."""
    if not support:
        return math.inf
    columns = A[:, list(support)]
    xi, sse = _solve(A, b, support)
    dof = max(len(b) - len(support), 1)
    variance = (sse / dof) * torch.linalg.pinv(columns.T @ columns).diagonal()
    return float((xi.abs() / variance.clamp_min(1e-300).sqrt()).min())


@dataclass(frozen=True)
class SparseRegression:
    """The sparse regression of discovery (module docstring), a pluggable optimizer as PySINDy's.

    Args:
        max_terms: largest support considered.
        min_t: smallest t-statistic $|\\xi_i|/\\sigma_i$ of a kept coefficient (its standard error from the
            least-squares covariance $\\hat\\sigma^2 (A_S^\\top A_S)^{-1}$): a support with a coefficient that
            the data do not determine (collinear columns) is not proposed.
        thresholds: the STLSQ thresholds $\\lambda$ swept, as shares of $\\|b\\|$.
    """

    max_terms: int = 4
    thresholds: tuple[float, ...] = THRESHOLDS
    min_t: float = 2.0

    def select(self, A: torch.Tensor, measured: torch.Tensor, guides: Sequence[torch.Tensor] = ()) -> list[int]:
        """The support of lowest extended BIC against ``measured`` (module docstring).

        Args:
            A: library columns of unit norm, (samples, terms).
            measured: the target whose residual is noise (scores the supports), (samples,).
            guides: further targets whose STLSQ paths propose supports (a denoised view of the same thing).
        """
        supports = {tuple(s) for s in forward_selection(A, measured, self.max_terms)} | {()}
        for target in (measured, *guides):
            supports |= {tuple(stlsq(A, target, lam)) for lam in self.thresholds}
        n = len(measured)
        scored = [(extended_bic(_solve(A, measured, s)[1], n, len(s), A.shape[1]), s) for s in supports
                  if len(s) <= self.max_terms and _t_statistic(A, measured, s) >= self.min_t]
        return list(min(scored)[1])
