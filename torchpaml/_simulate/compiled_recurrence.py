r"""The constant linear recurrence $z_{s+1} = A z_s + b_s$ stepped sequentially in C.

One loop over the steps, for each row of the batch: $z_{s+1,i} = \big(\sum_j A_{ij} z_{s,j}\big) + b_{s,i}$, the sum
in ascending $j$, compiled without contraction (:data:`~torchpaml._symbolic.compiler.FLAGS`), so every machine
computes the same numbers. It is the recursion that :func:`~torchpaml._simulate.scan.constant_recurrence`'s scan
reorganises, at about a tenth of its cost on one core (its $n^2$ products per step against the scan's dispatched
levels and copies): 0.6 ms against 5.4 ms for six rows of 10 000 steps of a fifth-order filter.

The library is built once per machine (:func:`~torchpaml._symbolic.compiler.cached_library`). Where it cannot be built
or loaded, where a ``torch.func`` transform is running, or for tensors that are not float64 on the CPU,
:func:`sequential_recurrence` gives ``None`` and the scan runs instead (one
:class:`~torchpaml.CompiledPathWarning` per process says why).
"""

from __future__ import annotations

import ctypes
import functools

import torch

from torchpaml._simulate.compiled import _transformed, warn_once
from torchpaml._symbolic.compiler import UnbuildableError, cached_library, loaded

__all__ = ["sequential_recurrence"]

_SOURCE = r"""
int recurrence(int rows, int steps, int n, const double *A, const double *b, const double *z0, double *z) {
    for (int r = 0; r < rows; r++) {
        const double *drive = b + (long)r * steps * n;
        double *zr = z + (long)r * (steps + 1) * n;
        for (int i = 0; i < n; i++) zr[i] = z0[(long)r * n + i];
        for (long k = 0; k < steps; k++) {
            const double *x = zr + k * n;
            double *next = zr + (k + 1) * n;
            for (int i = 0; i < n; i++) {
                double s = 0.0;
                for (int j = 0; j < n; j++) s += A[i * n + j] * x[j];
                next[i] = s + drive[k * n + i];
            }
        }
    }
    return 0;
}
"""


@functools.cache
def _function():
    """The compiled ``recurrence``, ``None`` where this machine cannot build or load it (warned once)."""
    try:
        function = loaded(cached_library(_SOURCE, "recurrence", "the compiled linear recurrence")).recurrence
    except UnbuildableError as error:
        warn_once(str(error))
        return None
    function.restype = ctypes.c_int
    function.argtypes = [ctypes.c_int] * 3 + [ctypes.c_void_p] * 4
    return function


def sequential_recurrence(A: torch.Tensor, b: torch.Tensor, z0: torch.Tensor) -> torch.Tensor | None:
    """$z_0$ and $z_{s+1} = A z_s + b_s$, A (n, n), b (batch, K, n), z0 (batch, n) -> z (batch, K + 1, n), without
    gradients; ``None`` where the module docstring leaves it to the scan."""
    tensors = (A, b, z0)
    if _transformed() or any(x.dtype != torch.float64 or x.device.type != "cpu" for x in tensors):
        return None
    function = _function()
    if function is None:
        return None
    A, b, z0 = (x.detach().contiguous() for x in tensors)
    batch, steps, n = b.shape
    z = torch.empty(batch, steps + 1, n, dtype=torch.float64)
    function(batch, steps, n, A.data_ptr(), b.data_ptr(), z0.data_ptr(), z.data_ptr())
    return z
