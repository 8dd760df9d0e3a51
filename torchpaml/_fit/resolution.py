r"""The step check: a fitted model's output must not depend on the RK4 step.

The RK4 engine advances each sample interval $h$ in $m$ = ``physics.substeps`` steps. After a fit, the
records are simulated again at $2m$; the gap

$$ g = \frac{\|\hat y_m - \hat y_{2m}\|}{\|y\|} $$

estimates the discretisation error of $\hat y_m$ (RK4 is fourth order: that error is $\tfrac{16}{15}g$
where the solution is smooth). The fit stands when $g \le$ :data:`STEP_TOLERANCE` $\cdot\,\|r\|$, with
$\|r\| = \|y - \hat y\|/\|y\|$ the misfit, or when $g \le$ :data:`STEP_FLOOR` (a noiseless record fitted
exactly): the step then moves a printed mismatch by a tenth of it at most. Otherwise $m$ grows by the
power of two that fourth order predicts brings $g$ to half the tolerance
(:func:`~torchpaml._simulate.step_control.next_substeps`, the rule :func:`~torchpaml.simulate`'s own step
doubling follows), and the fit goes on from its optimum at the finer step, until the check passes.

Beyond :data:`MAX_SUBSTEPS` it raises :class:`~torchpaml._errors.ResolutionError`: a rate of the fitted
model is far faster than the sampling (a spill at 40 1/s in a record sampled every 4 s), and the fit
settles where RK4's error, not the physics, explains the data. The fix is to bound that rate, or to
sample faster. Records on the exact path (linear physics on a uniform grid) have no step error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from torchpaml._data import Experiment
from torchpaml._errors import ResolutionError
from torchpaml._simulate.lti import exact_step
from torchpaml._simulate.records import simulate_record
from torchpaml._simulate.step_control import MAX_SUBSTEPS, next_substeps

__all__ = ["MAX_SUBSTEPS", "STEP_FLOOR", "STEP_TOLERANCE", "resolved_substeps", "step_gap"]

STEP_TOLERANCE = 0.1
STEP_FLOOR = 1e-6


def step_gap(physics, records: Sequence[Experiment], states: Sequence[torch.Tensor | None]) -> float:
    """$g$ (module docstring) over the records that RK4 simulates, from each record's initial state (or rest);
    0 where every record takes the exact path."""
    m = physics.substeps
    squared, norm = 0.0, 0.0
    for record, x0 in zip(records, states, strict=True):
        if exact_step(physics, record.t) is not None:
            continue
        coarse = simulate_record(physics, record, x0)
        fine = simulate_record(physics, record, x0, substeps=2 * m)
        squared += float((coarse - fine).square().sum())
        norm += float(record.y.square().sum())
    return 0.0 if norm == 0.0 else math.sqrt(squared / norm)


def resolved_substeps(physics, records: Sequence[Experiment], states: Sequence[torch.Tensor | None],
                      misfit: float) -> int:
    """The substeps at which the fitted ``physics`` passes the step check (module docstring): its own where it
    passes, else the next power-of-two multiple predicted to pass. Raises
    :class:`~torchpaml._errors.ResolutionError` beyond :data:`MAX_SUBSTEPS`."""
    m = physics.substeps
    gap = step_gap(physics, records, states)
    allowed = STEP_TOLERANCE * misfit
    if gap <= max(allowed, STEP_FLOOR):
        return m
    following = next_substeps(m, gap, max(allowed, STEP_FLOOR))
    if following > MAX_SUBSTEPS:
        step = float(records[0].t[1] - records[0].t[0])
        raise ResolutionError(
            f"{physics.display_name}'s fitted output depends on the RK4 step: halving the step at {m} substeps per "
            f"sample moves it by {100 * gap:.3g} % of the output, against a misfit of {100 * misfit:.3g} %, and "
            f"resolving it needs more than {MAX_SUBSTEPS} substeps. A rate of the fitted model is far faster than "
            f"the sampling (h = {step:g} s), and the fit settled where the integration error explains the data. "
            f"Bound that rate (physics.bound(name, lower, upper)) to what the sampling resolves, or sample faster. "
            f"Parameters: {physics.physical_parameters()}")
    return following
