r"""The spread of a physical parameter across a fleet of units, and the units that stand out.

Units of one design differ by their manufacturing tolerance, so a parameter's spread across the
fleet is part of the design, not a fault. A unit **stands out** when its estimate $\hat\theta_u$ lies
beyond the reach of both its own standard error $s_u$ and the fleet's robust spread $\sigma$ from the
fleet's median $m$:

$$ |\hat\theta_u - m| > k\,\sqrt{s_u^2 + \sigma^2}, \qquad \sigma = 1.4826\,\mathrm{MAD}, \qquad k = 3 , $$

with MAD the median absolute deviation from $m$ (1.4826 MAD estimates a normal spread's standard
deviation and is not pulled by the outliers it looks for). With $\sigma = 0$ this is the plain
reach of the unit's standard error; with precise estimates, as a fleet's usually are, $\sigma$ decides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["REACH", "ParameterSpread", "fleet_spread", "parameter_spread"]

#: How many combined standard deviations from the median make a unit stand out.
REACH = 3.0
#: MAD to standard deviation, for normal data.
MAD_TO_STD = 1.4826


@dataclass
class ParameterSpread:
    """One parameter across the units that have it: values and standard errors (units,), median, robust
    spread ``sigma``, and the units that stand out (module docstring)."""

    name: str
    units: list[str]
    values: np.ndarray
    stds: np.ndarray
    median: float
    sigma: float
    outliers: list[str]


def parameter_spread(parameters: dict[str, dict[str, float]],
                     uncertainty: dict[str, dict[str, float | None]]) -> list[ParameterSpread]:
    """Per parameter that at least three units have, its spread (module docstring).

    Args:
        parameters: unit -> {parameter: fitted value}.
        uncertainty: unit -> {parameter: standard error}; a missing one counts as 0, and ``None`` (a parameter
            the unit's records do not determine) as infinite: such a unit is never an outlier in it.
    """
    names = sorted({name for values in parameters.values() for name in values})
    spreads = []
    for name in names:
        units = sorted(u for u, values in parameters.items() if name in values)
        if len(units) < 3:
            continue
        values = np.array([parameters[u][name] for u in units], dtype=float)
        stds = np.array([uncertainty.get(u, {}).get(name, 0.0) for u in units], dtype=float)  # None -> nan
        stds = np.where(np.isnan(stds), np.inf, stds)
        median = float(np.median(values))
        sigma = MAD_TO_STD * float(np.median(np.abs(values - median)))
        reach = REACH * np.sqrt(stds**2 + sigma**2)
        outliers = [u for u, far in zip(units, np.abs(values - median) > reach, strict=True) if far]
        spreads.append(ParameterSpread(name, units, values, stds, median, sigma, outliers))
    return spreads


def fleet_spread(fleet: dict) -> list[ParameterSpread]:
    """:func:`parameter_spread` of the healthy units (no ``error``) of a fleet's ``fleet.json`` content."""
    healthy = [row for row in fleet["units"] if row["error"] is None]
    return parameter_spread({r["unit"]: r["parameters"] for r in healthy}, {r["unit"]: r["uncertainty"] for r in healthy})
