r"""A fit's time budget and its progress lines: a long fit never looks like a hang, and never runs away.

A :class:`Budget` is handed to :func:`~torchpaml.fit_physics` (``budget=``), which reports each evaluation
(a simulation with its Jacobian) to :meth:`Budget.check`. Every :data:`PROGRESS_SECONDS` the budget logs a progress
line (evaluations, the cost $\tfrac12\|r\|^2$ so far, the seconds spent and allowed); past its limit it raises
:class:`OverBudget`, which ends the fit. The limit is checked between evaluations, so a fit overruns it by at most
one evaluation.

While a fit evaluates, its budget is the *active* one (:meth:`Budget.active`), and the simulation engine calls
:func:`checkpoint` at every Newton sweep: an evaluation that runs away inside the engine (Newton that does not settle
and lengthens its segments towards sequential stepping) stops there too, not only between evaluations.

**The limit is a count of evaluations**, the same on every machine: a fit may take $E$ evaluations, and
:class:`OverBudget` ends it after the $E$-th. A time enters only as a safety net: the diagnosis' deadline (and a user's
own ``seconds``), checked between evaluations and at every Newton sweep of the engine; where it binds, the fit's
progress line says that the wall clock stopped it, and the answer may then depend on the machine's speed.

The ranking gives each refit ten times its rung's own fit in evaluations (:data:`REFIT_BUDGET`), and never less than ten
times a refit's own iteration limit: $E = 10\,\max(n_{\text{fit}}, n_{\max})$ (:func:`refit_evaluations`). Without the
floor, a rung fitted from its refit's optimum in 6 or 7 evaluations (the cascaded tanks' last rung, the records
perturbed by 1e-12 or not) gave its probes' refits 60 or 70, and a refit that needed 65 was decided on one and not on
the other.
A rung's fit is all the fitting that made its model: the fit of the physics on the first rung; on the next ones, the
refit that found the added effect and the fit that takes it to the last digits. A rung's fit from its refit's optimum
(which stopped at a criterion step of 0.1) needs a few evaluations: it may take :data:`RUNG_FIT_BUDGET` times its
refit's, and one over it leaves the rung at its refit's parameters, and says so. The discovery's closed-form refits are
several fits each (the form, its pruning, what remains): they may take ten fits of ``max_nfev`` evaluations.

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
           "checkpoint", "refit_evaluations"]

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


def refit_evaluations(share: float, rung_fit: int, max_nfev: int) -> float:
    """The evaluations a refit may take (module docstring): ``share`` times its rung's fit (``rung_fit``
    evaluations), and at least ``share`` times a refit's iteration limit ``max_nfev``."""
    return share * max(rung_fit, max_nfev)


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
    """A fit stopped at its budget; ``seconds`` is the time it had run, ``evaluations`` the evaluations it made."""

    def __init__(self, label: str, seconds: float, limit: str, evaluations: int = 0):
        super().__init__(f"{label} stopped over its budget after {evaluations} evaluations and {seconds:.1f} s "
                         f"(budget {limit})")
        self.seconds, self.evaluations = seconds, evaluations


@dataclass
class Budget:
    """The evaluations a fit may take, with the wall clock as a safety net (module docstring), counted from its
    creation.

    Args:
        label: what the progress lines call the fit, e.g. ``"refitting Pendulum + dynamic_friction"``.
        seconds: a wall-clock limit in seconds (default none): a safety net, which makes a result depend on the
            machine's speed where it binds.
        evaluations: $E$, the evaluations the fit may make (default none).
        deadline: an absolute ``time.perf_counter()`` by which the fit must end (default none).
    """

    label: str
    seconds: float | None = None
    evaluations: float | None = None
    deadline: float = math.inf
    started: float = field(default_factory=time.perf_counter, init=False)
    count: int = field(default=0, init=False)
    _reported: float = field(default=0.0, init=False, repr=False)

    @property
    def elapsed(self) -> float:
        """Seconds since the budget was created."""
        return time.perf_counter() - self.started

    @property
    def limit(self) -> float:
        """The wall-clock limit in seconds: ``seconds`` where given, capped by the deadline."""
        cap = self.deadline - self.started
        return cap if self.seconds is None else min(self.seconds, cap)

    def restarted(self, label: str, share: float = 1.0) -> Budget:
        """A budget with ``share`` of these limits (the deadline whole), for another fit called ``label``, counted
        from now."""
        return Budget(label, None if self.seconds is None else share * self.seconds,
                      None if self.evaluations is None else share * self.evaluations, self.deadline)

    def describe(self) -> str:
        """The limits in words, for a progress line: ``"150 evaluations, within the deadline in 580 s"``."""
        parts = [f"{self.evaluations:.0f} evaluations"] if self.evaluations is not None else []
        if self.seconds is not None:
            parts.append(f"{self.seconds:.3g} s")
        own = " and ".join(parts)
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
        """Raise :class:`OverBudget` past the wall-clock limit, saying that the clock bound."""
        elapsed = self.elapsed
        if elapsed > self.limit:
            log.info("%s: stopped by the wall clock after %.1f s (%s): on a faster machine it could have gone on",
                     self.label, elapsed, self.describe())
            raise OverBudget(self.label, elapsed, f"{self.limit:.1f} s of wall clock", self.count)

    def check(self, cost: float, evaluation_seconds: float) -> None:
        """Report an evaluation (of ``evaluation_seconds``) whose fit's lowest cost so far is ``cost``: log progress
        every :data:`PROGRESS_SECONDS` (the evaluations of every fit under this budget, counted together), raise
        :class:`OverBudget` once the evaluations reach their limit, or past the wall-clock limit."""
        self.count += 1
        elapsed = self.elapsed
        if elapsed - self._reported >= PROGRESS_SECONDS:
            self._reported = elapsed
            lowest = f"cost {cost:.6g}" if math.isfinite(cost) else "no finite cost yet"
            log.info("%s: %d evaluations, %s, %.0f s (budget %s)", self.label, self.count, lowest, elapsed,
                     self.describe())
        if self.evaluations is not None and self.count >= self.evaluations:
            raise OverBudget(self.label, elapsed, f"{self.evaluations:.0f} evaluations", self.count)
        self.enforce()
