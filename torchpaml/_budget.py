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

The ranking gives each refit ten times its rung's own fit (:data:`REFIT_BUDGET`), in seconds and in evaluations:
$T = 10\,t_{\text{fit}}$ and $E = 10\,n_{\text{fit}}$, its fit's evaluations redone at the refit's own cost $t_1$.
A rung's fit is all the fitting that made its model: the fit of the physics on the first rung; on the next ones, the
refit that found the added effect and the fit that takes it to the last digits. The evaluations count where the
rung simulates on a cheaper path than the refit: a linear rung's exact path, against the nonlinear engine of any
refit on it, or a refit whose model carries states of its own. A rung's fit from its refit's optimum (which stopped
at a criterion step of 0.1) needs a few evaluations: it may take :data:`RUNG_FIT_BUDGET` times its refit, and one
over it leaves the rung at its refit's parameters, and says so. The discovery's closed-form refits are several fits
each (the form, its pruning, what remains): they may take ten fits of ``max_nfev`` evaluations at their own cost.

The whole diagnosis has a deadline, :data:`DEFAULT_BUDGET` seconds by default, printed in its first line: a fit
still running then stops, and those not started are not run (reported undecided). Being a time, a limit binds at a
point that moves with the machine's speed: a candidate it stops is reported undecided, never decided by it.
"""

from __future__ import annotations

from torchpaml._errors import ConfigurationError

import contextvars
import logging
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

__all__ = ["Budget", "DEFAULT_BUDGET", "OverBudget", "PROGRESS_SECONDS", "REFIT_BUDGET", "RUNG_FIT_BUDGET",
           "checkpoint"]

log = logging.getLogger(__name__)

#: Seconds between a fit's progress lines.
PROGRESS_SECONDS = 5.0
#: A ranking's refit may take this many times its rung's own fit (module docstring).
REFIT_BUDGET = 10.0
#: A rung's fit from the optimum of the refit that found its effect may take this many times that refit: it needs a
#: few evaluations (2 to 5 times the refit on the cascaded tanks), and one that runs away takes 50 to 150 times it (a
#: sharp LuGre friction's): the limit lies in the gap, far from both, so that no machine's speed moves a rung across it.
RUNG_FIT_BUDGET = 10.0
#: Seconds a whole diagnosis may take by default (``diagnose(budget=)``, ``--budget``): ten minutes.
DEFAULT_BUDGET = 600.0
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


def check_budget(budget: float | None) -> None:
    """Refuse a whole diagnosis' ``budget`` (seconds, or ``None``: no limit) that cannot work."""
    if budget is not None and not budget > 0:
        raise ConfigurationError(f"budget is the seconds the whole diagnosis may take, > 0; got {budget}")


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

    def restarted(self, label: str, share: float = 1.0) -> Budget:
        """A budget with ``share`` of these limits (the deadline whole), for another fit called ``label``, counted
        from now."""
        return Budget(label, None if self.seconds is None else share * self.seconds,
                      None if self.evaluations is None else share * self.evaluations, self.deadline)

    def describe(self) -> str:
        """The limits in words, for a progress line: ``"12 s"``, ``"the longer of 12 s and 150 evaluations at its own
        cost, within the deadline in 580 s"``."""
        own = f"{self.seconds:.3g} s" if self.seconds is not None else ""
        if self.evaluations is not None:
            evaluations = f"{self.evaluations:.0f} evaluations at its own cost"
            own = f"the longer of {own} and {evaluations}" if own else evaluations
        if self.deadline == math.inf:
            return own or "no limit"
        deadline = f"the deadline in {max(self.deadline - time.perf_counter(), 0.0):.0f} s"
        return f"{own}, within {deadline}" if own else deadline

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
