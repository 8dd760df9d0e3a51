r"""A fit's time budget and its progress lines: a long fit never looks like a hang, and never runs away.

A :class:`Budget` is handed to :func:`~torchpaml.fit_physics` (``budget=``), which reports each evaluation
(a simulation with its Jacobian) to :meth:`Budget.check`. Every :data:`PROGRESS_SECONDS` the budget logs a progress
line (evaluations, the cost $\tfrac12\|r\|^2$ so far, the seconds spent and allowed); past its limit it raises
:class:`OverBudget`, which ends the fit. The limit is checked between evaluations, so a fit overruns it by at most
one evaluation.

While a fit evaluates, its budget is the *active* one (:meth:`Budget.active`), and the simulation engine calls
:func:`checkpoint` at every Newton sweep: an evaluation that runs away inside the engine (Newton that does not settle
and lengthens its segments towards sequential stepping) stops there too, not only between evaluations.

The limit is the larger of a time in seconds and a count of evaluations at the fit's own cost per evaluation,
capped by an absolute deadline:

$$ \text{limit} = \min\big(\max(T,\; E\,t_1),\; t_{\text{deadline}} - t_{\text{start}}\big), $$

where $t_1$ is the costliest of the fit's first :data:`SCALE_EVALUATIONS` evaluations; until the first one ends, the
deadline alone limits the fit.

The ranking gives each refit $T = 10\,t_{\text{fit}}$, ten times its rung's own fit, and $E = 10\,n_{\max}$, ten full
refits (``max_nfev`` evaluations each) at the refit's own cost per evaluation (:data:`REFIT_BUDGET`). The
second term matters where the rung simulates on a cheaper path than the refit (a linear rung's exact path). So the
budget binds where a refit's evaluations grow far costlier than its first (its parameters drift towards a stiff
or unsettled model) or it needs far more of them than a fit may take, and not where a refit merely runs on the
nonlinear engine. Being a time, it binds at a point that moves with the machine's speed: a candidate it stops is
reported undecided, never decided by it.
"""

from __future__ import annotations

import contextvars
import logging
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

__all__ = ["Budget", "OverBudget", "PROGRESS_SECONDS", "REFIT_BUDGET", "checkpoint"]

log = logging.getLogger(__name__)

#: Seconds between a fit's progress lines.
PROGRESS_SECONDS = 5.0
#: A ranking's refit may take this many times its rung's own fit (module docstring).
REFIT_BUDGET = 10.0
#: $t_1$ is the costliest of a fit's first this many evaluations: the step check at a fit's start may raise the
#: substeps after the first one (a discovery screen of the pendulum was stopped at 0.5 s, 100 times a first
#: evaluation that the next ones outcost).
SCALE_EVALUATIONS = 3


_ACTIVE: contextvars.ContextVar[Budget | None] = contextvars.ContextVar("torchpaml_budget", default=None)


def checkpoint() -> None:
    """Raise :class:`OverBudget` if the active budget (:meth:`Budget.active`) is past its limit; else nothing."""
    budget = _ACTIVE.get()
    if budget is not None:
        budget.enforce()


class OverBudget(RuntimeError):
    """A fit stopped at its budget; ``seconds`` is the time it had run."""

    def __init__(self, label: str, seconds: float, limit: float):
        super().__init__(f"{label} stopped over its budget after {seconds:.1f} s (budget {limit:.1f} s)")
        self.seconds = seconds


@dataclass
class Budget:
    """The time a fit may take (module docstring), counted from its creation.

    Args:
        label: what the progress lines call the fit, e.g. ``"refitting Pendulum + dynamic_friction"``.
        seconds: $T$, the limit in seconds (default none).
        evaluations: $E$, the limit in evaluations at the fit's cost per evaluation, $t_1$ (default none). With
            neither, only the deadline limits the fit.
        deadline: an absolute ``time.perf_counter()`` by which the fit must end (default none).
    """

    label: str
    seconds: float | None = None
    evaluations: float | None = None
    deadline: float = math.inf
    started: float = field(default_factory=time.perf_counter, init=False)
    count: int = field(default=0, init=False)
    _scale: float | None = field(default=None, init=False, repr=False)
    _reported: float = field(default=0.0, init=False, repr=False)

    @property
    def elapsed(self) -> float:
        """Seconds since the budget was created."""
        return time.perf_counter() - self.started

    @property
    def limit(self) -> float:
        """The limit in seconds. Until the first evaluation has ended, the deadline alone: that evaluation sets the
        scale of $E$, and a first evaluation cut short would leave a refit undecided on a machine that is merely slow."""
        cap = self.deadline - self.started
        if self._scale is None or (self.seconds is None and self.evaluations is None):
            return cap
        return min(max(self.seconds or 0.0, (self.evaluations or 0.0) * self._scale), cap)

    def restarted(self, label: str) -> Budget:
        """A budget with these limits, for another fit called ``label``, counted from now."""
        return Budget(label, self.seconds, self.evaluations, self.deadline)

    @property
    def expired(self) -> bool:
        """Whether the deadline has passed (checked before a fit starts)."""
        return time.perf_counter() >= self.deadline

    @contextmanager
    def active(self):
        """Make this the budget that :func:`checkpoint` enforces while the block runs (an evaluation of its fit)."""
        token = _ACTIVE.set(self)
        try:
            yield self
        finally:
            _ACTIVE.reset(token)

    def enforce(self) -> None:
        """Raise :class:`OverBudget` past the limit."""
        elapsed = self.elapsed
        if elapsed > self.limit:
            raise OverBudget(self.label, elapsed, self.limit)

    def check(self, cost: float, evaluation_seconds: float) -> None:
        """Report an evaluation whose fit's lowest cost so far is ``cost``: log progress every :data:`PROGRESS_SECONDS`
        (the evaluations of every fit under this budget, counted together), raise :class:`OverBudget` past the limit."""
        self.count += 1
        if self.count <= SCALE_EVALUATIONS:  # the scale: the costliest of the first few evaluations
            self._scale = max(self._scale or 0.0, evaluation_seconds)
        elapsed = self.elapsed
        limit = self.limit
        if elapsed - self._reported >= PROGRESS_SECONDS:
            self._reported = elapsed
            allowed = "" if limit == math.inf else f" of {limit:.0f} s"
            lowest = f"cost {cost:.6g}" if math.isfinite(cost) else "no finite cost yet"
            log.info("%s: %d evaluations, %s, %.0f s%s", self.label, self.count, lowest, elapsed, allowed)
        self.enforce()
