r"""How sure the fitted parameters are: standard errors, 95 % intervals and an identifiability check.

At the optimum $\hat\theta$ of an output-error fit with $N$ residuals $r$ and $p$ parameters, the
linearised covariance (what MATLAB's ``present`` reports) is

$$ \widehat{\mathrm{Cov}}(\hat\theta) = s^2 (J^\top J)^{-1}, \qquad s^2 = \frac{\|r\|^2}{N - p}, \qquad
   J = \frac{\partial r}{\partial\theta} = \frac{\partial r}{\partial\rho}\,\Big/\,\frac{d\theta}{d\rho} , $$

with $J$ in physical units (the fit works on the raw values $\rho$; the chain rule divides by the
constraint map's slope). Standard errors are $\sqrt{\mathrm{diag}}$, the 95 % intervals
$\hat\theta \pm t_{0.975,\,N-p}\,\mathrm{se}$. They assume a white residual: a coloured one (wrong
physics, coloured noise) makes them too narrow.

**Identifiability** (Brun, Reichert & Künsch 2001): with the columns of $J$ scaled to unit norm, $\tilde J$,
the collinearity index is $\gamma = 1/\sqrt{\lambda_{\min}(\tilde J^\top\tilde J)}$. Above
:data:`COLLINEARITY_LIMIT` a combination of parameters moves the output hardly at all; the
eigenvector of $\lambda_{\min}$ names it. The index does not shrink with more data, so a long record
can pin a collinear combination down anyway: the warning is given only when a parameter of the
combination is also loose, its relative standard error above :data:`LOOSE` (or it does not move the
output at all).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import torch
from scipy.stats import t as student_t

from torchpaml._physics.base import AbstractPhysics

__all__ = ["COLLINEARITY_LIMIT", "LOOSE", "IdentifiabilityWarning", "Uncertainty", "constraint_slopes", "parameter_uncertainty"]

#: Brun et al. (2001) call a parameter set poorly identifiable above a collinearity index of 10 to 15.
COLLINEARITY_LIMIT = 15.0
#: A parameter whose standard error exceeds this share of its value is loosely determined.
LOOSE = 0.1


class IdentifiabilityWarning(UserWarning):
    """The records do not determine a parameter, or a combination of parameters."""


@dataclass
class Uncertainty:
    """Standard errors and 95 % intervals of fitted parameters, in physical units (module docstring).

    Attributes:
        std: ``{name: standard error}``; ``inf`` where the records do not determine the parameter.
        interval: ``{name: (lower, upper)}``, the 95 % confidence interval.
        correlation: (p, p) correlation matrix of the estimates, in the order of ``std``.
        collinearity: the collinearity index $\\gamma$.
        warning: the identifiability warning, or ``None``.
    """

    std: dict[str, float]
    interval: dict[str, tuple[float, float]]
    correlation: torch.Tensor
    collinearity: float
    warning: str | None


def constraint_slopes(physics: AbstractPhysics, names: list[str]) -> torch.Tensor:
    r"""$d\theta/d\rho$ of each named parameter's constraint map at its current raw value, (p,).

    A central difference (step 1e-6 max(1, |rho|)) of the smooth map, so that it also works where
    autograd is off (Lightning's test loop runs in inference mode).
    """
    slopes = []
    for name in names:
        owner, leaf = physics._owner(name)
        parametrization = getattr(owner.parametrizations, leaf)
        raw = parametrization.original.detach()
        step = 1e-6 * max(1.0, float(raw.abs()))
        with torch.no_grad():
            slopes.append((parametrization[0](raw + step) - parametrization[0](raw - step)) / (2 * step))
    return torch.stack(slopes) if slopes else torch.zeros(0, dtype=torch.float64)


def _combination(names: list[str], values: torch.Tensor, direction: torch.Tensor, norms: torch.Tensor) -> str:
    """The unresolved direction in words, e.g. ``zeta +1 % with gain -0.83 %``.

    ``direction`` (p,) is the eigenvector in unit-norm sensitivity coordinates; parameters with a
    component above 0.2 take part. Each is given as a relative change (or absolute, at value 0),
    scaled so that the largest relative change is 1 %.
    """
    step = direction / norms  # physical units: along this step the output barely moves
    involved = [i for i in range(len(names)) if abs(float(direction[i])) > 0.2]
    relative = {i: float(step[i] / values[i].abs()) for i in involved if float(values[i]) != 0}
    scale = 0.01 / max((abs(r) for r in relative.values()), default=1.0)
    return " with ".join(f"{names[i]} {100 * scale * relative[i]:+.2g} %" if i in relative
                         else f"{names[i]} {scale * float(step[i]):+.3g}" for i in involved)


def parameter_uncertainty(names: list[str], values: torch.Tensor, residual: torch.Tensor,
                          jacobian: torch.Tensor, at_limit: list[str] = ()) -> Uncertainty:
    r"""Uncertainty of the estimates ``values`` (p,) of ``names`` at a least-squares optimum (module docstring).

    Args:
        names: the fitted unknowns (parameters, and initial states where they were estimated).
        values: their estimates, in physical units.
        residual: $r$ at the optimum, (N,).
        jacobian: $\partial r/\partial\theta$ in physical units, (N, p), columns in the order of ``names``
            (raw-coordinate columns divided by :func:`constraint_slopes`).
        at_limit: parameters at the limit of their constraint (a positive rate driven to 0, where the
            constraint's slope vanishes): their standard error is undefined (``inf``), the others are
            computed without them, and the warning names them.
    """
    if not names:
        return Uncertainty({}, {}, torch.zeros(0, 0, dtype=torch.float64), 1.0, None)
    if at_limit:
        keep = [i for i, n in enumerate(names) if n not in at_limit]
        inner = parameter_uncertainty([names[i] for i in keep], values[keep], residual, jacobian[:, keep])
        std = {n: inner.std.get(n, math.inf) for n in names}
        interval = {n: inner.interval.get(n, (float(v), math.inf) if float(v) >= 0 else (-math.inf, float(v)))
                    for n, v in zip(names, values, strict=True)}
        note = (f"{', '.join(at_limit)} ended at the limit of its constraint (the data drive it there: the physics "
                "may not need that term)")
        return Uncertainty(std, interval, inner.correlation, inner.collinearity,
                           note if inner.warning is None else f"{note}; {inner.warning}")
    dof = residual.numel() - len(names)
    variance = float(residual @ residual) / max(dof, 1)
    norms = torch.linalg.vector_norm(jacobian, dim=0)
    dead = [n for n, norm in zip(names, norms, strict=True) if float(norm) == 0.0]
    scaled = jacobian / torch.where(norms > 0, norms, torch.ones_like(norms))
    try:
        eigenvalues, eigenvectors = torch.linalg.eigh(scaled.T @ scaled)
        smallest = float(eigenvalues[0])
    except torch.linalg.LinAlgError:  # a non-finite sensitivity: nothing can be said
        eigenvalues, eigenvectors, smallest = None, torch.eye(len(names), dtype=torch.float64), 0.0
    collinearity = math.inf if not smallest > 1e-300 else 1.0 / math.sqrt(smallest)
    if dead or collinearity > 1e12:
        covariance = torch.full((len(names), len(names)), math.inf, dtype=torch.float64)
        std = torch.full((len(names),), math.inf, dtype=torch.float64)
        correlation = torch.full_like(covariance, math.nan)
    else:  # (J^T J)^-1 through the scaled, better conditioned matrix
        inverse = eigenvectors @ torch.diag(1 / eigenvalues) @ eigenvectors.T
        covariance = variance * inverse / torch.outer(norms, norms)
        std = covariance.diagonal().sqrt()
        correlation = covariance / torch.outer(std, std)
    quantile = float(student_t.ppf(0.975, max(dof, 1)))
    warning = None
    if eigenvalues is None:
        warning = ("the output's sensitivities are not finite at the optimum (a square root or a kink at a state "
                   "of 0?): the uncertainty is unknown; check the physics where the states reach its limits")
    elif dead:
        warning = (f"{', '.join(dead)} do(es) not change the simulated output at all: the records cannot determine "
                   "it; fix it, or record an experiment that excites it")
    elif collinearity > COLLINEARITY_LIMIT and any(
            abs(float(eigenvectors[i, 0])) > 0.2 and float(std[i]) > LOOSE * abs(float(values[i]))
            for i in range(len(names))):
        warning = (f"the records do not determine {_combination(names, values, eigenvectors[:, 0], norms)} "
                   f"separately: that combination leaves the output almost unchanged (collinearity index "
                   f"{collinearity:.3g} > {COLLINEARITY_LIMIT:g}). Excite the device more richly (more frequencies "
                   "and amplitudes), or fix one of these parameters")
    return Uncertainty(
        {n: float(s) for n, s in zip(names, std, strict=True)},
        {n: (float(v - quantile * s), float(v + quantile * s)) for n, v, s in zip(names, values, std, strict=True)},
        correlation, collinearity, warning)


def warn_if_unidentifiable(uncertainty: Uncertainty, model: str) -> None:
    """Emit :class:`IdentifiabilityWarning` when ``uncertainty`` carries a warning."""
    if uncertainty.warning is not None:
        warnings.warn(f"{model}: {uncertainty.warning}", IdentifiabilityWarning, stacklevel=3)
