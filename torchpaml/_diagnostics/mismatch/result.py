"""What the probes found: one row per place (:class:`ProbeResult`), and the table of them (:class:`MismatchProbes`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from torchpaml._diagnostics.discovery.result import Discovery
from torchpaml._diagnostics.mismatch.in_time import ErrorInTime
from torchpaml._diagnostics.mismatch.places import FORCE
from torchpaml._diagnostics.results import ModelScore

__all__ = ["DISCOVERED", "GAIN_TIE", "MismatchProbes", "ProbeResult"]

#: Gains within this much of each other are the same evidence: they rank in the places' order, so that the same
#: records name the same place on every machine.
GAIN_TIE = 0.002
#: The note of the force place's row where the discovery's closed form is its best option.
DISCOVERED = "the discovery's closed form"


@dataclass
class ProbeResult:
    """One place's probe: the extension fitted there (a library effect's name, the discovered force's text, or
    ``"initial state"``), the model's validation mismatch with it (a fraction), and its validation gain, the share
    by which it lowers the model's validation mismatch: $1 - m_{\\text{probe}} / m_{\\text{model}}$. ``validation``
    and ``gain`` are ``None`` where nothing was fitted, and ``note`` says why; else it says what was tried."""

    place: str
    extension: str
    fitted: str | None = None
    validation: float | None = None
    gain: float | None = None
    note: str = ""
    #: the extended model's score (its parameters, errors and outputs); ``None`` where nothing was fitted
    score: ModelScore | None = field(default=None, repr=False)


@dataclass
class MismatchProbes:
    """Where the mismatch of ``model`` (the ladder's last rung, validation mismatch ``validation``) points: one
    :class:`ProbeResult` per place, the largest gain first; ``in_time``: where in time its validation error sits.
    ``reason``: why no probe ran (``rows`` is then empty)."""

    model: str
    validation: float
    rows: list[ProbeResult] = field(default_factory=list)
    in_time: ErrorInTime | None = None
    reason: str = ""
    #: the smallest gain that names a place (the selection rule's ``min_share``)
    min_gain: float = 0.05
    #: the places probed, in the prober's order (which ranks gains within :data:`GAIN_TIE`)
    places: tuple[str, ...] = ()

    def with_discovery(self, discovery: Discovery | None) -> MismatchProbes:
        """The table with the discovery's closed form as an option of the force's place (:data:`FORCE`): it takes the
        row where it lowers the validation mismatch more than the row's best library effect. The same table where
        no probe ran, no discovery ran, or it found no closed form."""
        found = None if discovery is None else discovery.discovered
        if not self.rows or found is None:
            return self
        gain = 1.0 - found.nrmse_validation / self.validation
        rows = [replace(row, fitted=discovery.text, validation=found.nrmse_validation, gain=gain, note=DISCOVERED,
                        score=found)
                if row.place == FORCE and (row.gain is None or gain > row.gain) else row for row in self.rows]
        return replace(self, rows=ranked(rows, list(self.places)))

    @property
    def best(self) -> ProbeResult | None:
        """The place whose probe gains most, where it gains at least :attr:`min_gain`; else ``None``."""
        first = self.rows[0] if self.rows else None
        return first if first is not None and first.gain is not None and first.gain >= self.min_gain else None

    def describe(self) -> str:
        """One sentence for the verdict: the best place, its extension and gain, then every other place's gain."""
        if not self.rows:
            return f"Where the mismatch points: not probed ({self.reason})."
        gains = [f"{r.place} {_percent(r.gain)} ({r.fitted})" for r in self.rows if r.gain is not None]
        best = self.best
        if best is None:
            return (f"Where the mismatch points: no probe lowers the validation mismatch by {100 * self.min_gain:.0f} % "
                    f"or more ({'; '.join(gains)}): the missing part is at none of these places.")
        return (f"Where the mismatch points: the {best.place} ({best.fitted}: validation {100 * self.validation:.2f} % "
                f"-> {100 * best.validation:.2f} %, a gain of {_percent(best.gain)}); the probes' gains: "
                f"{'; '.join(gains[1:]) or 'none other'}.")


def _percent(gain: float) -> str:
    value = round(100 * gain, 1)
    return f"{value + 0.0 if value else 0.0:.1f} %"  # no "-0.0"


def ranked(rows: list[ProbeResult], order: list[str]) -> list[ProbeResult]:
    """``rows`` by gain, largest first, those within :data:`GAIN_TIE` of the best of their group in ``order`` (the
    places'); rows without a gain last."""
    place = {name: i for i, name in enumerate(order)}
    result, group = [], []
    for row in sorted((r for r in rows if r.gain is not None), key=lambda r: -r.gain):
        if group and row.gain < group[0].gain - GAIN_TIE:
            result += sorted(group, key=lambda r: place[r.place])
            group = []
        group.append(row)
    result += sorted(group, key=lambda r: place[r.place])
    return result + [r for r in rows if r.gain is None]
