r"""Records checked against each other before a fit: each output channel varies, and each is in one unit across records.

* :func:`check_outputs_vary`: an output channel that holds one value at every sample of a record (a dead sensor, a
  column of zeros) carries nothing to fit and has no scale to weigh a fit by; it is refused in one line that names
  the channel.
* :func:`check_scales_agree`: a channel written in another unit in one record (millimetres in one file, metres in the
  next) is a factor of 100 or 1000 between records that the input does not show. For each record $r$ and output
  channel $c$ the ratio of its RMS to the first record's, divided by the same ratio of the first input,

  $$ q_{rc} = \frac{\mathrm{RMS}(y^{(r)}_c) / \mathrm{RMS}(y^{(1)}_c)}
                {\mathrm{RMS}(u^{(r)}_1) / \mathrm{RMS}(u^{(1)}_1)}, $$

  must lie within $[1/Q, Q]$, $Q$ = :data:`SCALE_RATIO`: one device's records, even in other regimes, do not change
  their output's level against their input's by that factor, and a unit's slip does.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from torchpaml._data.record import Record
from torchpaml._errors import DataError

__all__ = ["SCALE_RATIO", "check_outputs_vary", "check_scales_agree"]

#: The factor $Q$ beyond which an output channel's level, relative to the input's, differs between records
#: (module docstring): below the smallest unit slip (x100, centimetres for metres), above what a device shows.
SCALE_RATIO = 30.0


def _rms(values: torch.Tensor) -> torch.Tensor:
    """RMS over time of each column of ``values`` (time, C): (C,)."""
    return values.square().mean(dim=0).sqrt()


def check_outputs_vary(records: Sequence[Record]) -> None:
    """:class:`~torchpaml.DataError` naming the first output channel that is constant over a whole record."""
    for record in records:
        constant = (record.y.max(dim=0).values == record.y.min(dim=0).values).nonzero()
        if len(constant):
            c = int(constant[0])
            raise DataError(f"record {record.name!r}: output channel {record.output_names[c]!r} (column {c + 1} of y) "
                            f"is constant, {float(record.y[0, c]):.6g} at every sample: a dead sensor or an empty "
                            "column; fix the record, or drop the channel from the records and the physics' output")


def check_scales_agree(records: Sequence[Record]) -> None:
    """:class:`~torchpaml.DataError` naming the output channel whose level against the input differs between records
    by more than :data:`SCALE_RATIO` (module docstring); records without input (RMS 0) are compared by output alone."""
    first = records[0]
    for record in records[1:]:
        if record.y.shape[1] != first.y.shape[1]:
            return  # the physics' channel check names this mistake
        u_first, u_record = float(_rms(first.u)[0]), float(_rms(record.u)[0])
        input_ratio = u_record / u_first if u_first > 0 and u_record > 0 else 1.0
        ratios = _rms(record.y) / _rms(first.y).clamp_min(1e-300) / input_ratio
        for c, q in enumerate(ratios.tolist()):
            if not 1 / SCALE_RATIO <= q <= SCALE_RATIO:
                name, factor = record.output_names[c], max(q, 1 / q)
                larger = "larger" if q > 1 else "smaller"
                raise DataError(f"output {name!r} is {factor:.3g} times {larger}, against the input, in record "
                                f"{record.name!r} than in {first.name!r}: one of them is in another unit (mm for m?); "
                                f"give every record's {name!r} in one unit")
