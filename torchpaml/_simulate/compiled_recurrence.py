r"""The constant linear recurrence $z_{s+1} = A z_s + b_s$ stepped sequentially in C.

One loop over the steps, for each row of the batch: $z_{s+1,i} = \big(\sum_j A_{ij} z_{s,j}\big) + b_{s,i}$, the sum
in ascending $j$, compiled without contraction (:data:`~torchpaml._symbolic.compiler.FLAGS`), so every machine
computes the same numbers. It is the recursion that :func:`~torchpaml._simulate.scan.constant_recurrence`'s scan
reorganises, at about a tenth of its cost on one core (its $n^2$ products per step against the scan's dispatched
levels and copies): 0.6 ms against 5.4 ms for six rows of 10 000 steps of a fifth-order filter.

The library is built once per machine (:func:`~torchpaml._symbolic.compiler.cached_library`). Where it cannot be built
or loaded (one :class:`~torchpaml.CompiledPathWarning` per process says why), where a ``torch.func`` transform or
``torch.compile`` is running, or for tensors that are not float64 on the CPU, :func:`sequential_recurrence` and
:func:`sequential_forced` give ``None`` and torch runs instead (the scan).
"""

from __future__ import annotations

import ctypes
import functools

import torch

from torchpaml._simulate.compiled import transformed, warn_once
from torchpaml._symbolic.compiler import UnbuildableError, cached_library, loaded

__all__ = ["sequential_forced", "sequential_recurrence"]

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

/* The same loop driven by sampled inputs: b_s = G0 u_s + G1 u_{s+1}, each product summed in ascending order. */
int forced(int rows, int steps, int n, int m, const double *A, const double *G0, const double *G1, const double *u,
           const double *z0, double *z) {
    for (int r = 0; r < rows; r++) {
        const double *ur = u + (long)r * (steps + 1) * m;
        double *zr = z + (long)r * (steps + 1) * n;
        for (int i = 0; i < n; i++) zr[i] = z0[(long)r * n + i];
        for (long k = 0; k < steps; k++) {
            const double *x = zr + k * n, *now = ur + k * m, *later = now + m;
            double *next = zr + (k + 1) * n;
            for (int i = 0; i < n; i++) {
                double s = 0.0, first = 0.0, second = 0.0;
                for (int j = 0; j < n; j++) s += A[i * n + j] * x[j];
                for (int l = 0; l < m; l++) first += now[l] * G0[i * m + l];
                for (int l = 0; l < m; l++) second += later[l] * G1[i * m + l];
                next[i] = s + (first + second);
            }
        }
    }
    return 0;
}
"""


@functools.cache
def _library():
    """The compiled library, ``None`` where this machine cannot build or load it (warned once)."""
    try:
        library = loaded(cached_library(_SOURCE, "recurrence", "the compiled linear recurrence"))
    except UnbuildableError as error:
        warn_once(str(error))
        return None
    library.recurrence.restype = library.forced.restype = ctypes.c_int
    library.recurrence.argtypes = [ctypes.c_int] * 3 + [ctypes.c_void_p] * 4
    library.forced.argtypes = [ctypes.c_int] * 4 + [ctypes.c_void_p] * 6
    return library


def _usable(*tensors: torch.Tensor):
    """The library where these tensors may leave torch for it (module docstring), else ``None``."""
    if transformed() or torch.compiler.is_compiling():
        return None
    if any(x.dtype != torch.float64 or x.device.type != "cpu" for x in tensors):
        return None
    return _library()


def sequential_recurrence(A: torch.Tensor, b: torch.Tensor, z0: torch.Tensor) -> torch.Tensor | None:
    """$z_0$ and $z_{s+1} = A z_s + b_s$, A (n, n), b (batch, K, n), z0 (batch, n) -> z (batch, K + 1, n), without
    gradients; ``None`` where the module docstring leaves it to the scan."""
    library = _usable(A, b, z0)
    if library is None:
        return None
    A, b, z0 = (x.detach().contiguous() for x in (A, b, z0))
    batch, steps, n = b.shape
    z = torch.empty(batch, steps + 1, n, dtype=torch.float64)
    library.recurrence(batch, steps, n, A.data_ptr(), b.data_ptr(), z0.data_ptr(), z.data_ptr())
    return z


def sequential_forced(Phi: torch.Tensor, G0: torch.Tensor, G1: torch.Tensor, u: torch.Tensor,
                      x0: torch.Tensor) -> torch.Tensor | None:
    r"""$x_0$ and $x_{s+1} = \Phi x_s + (\Gamma_0 u_s + \Gamma_1 u_{s+1})$, Phi (n, n), G0 and G1 (n, m), u (batch,
    time, m), x0 (batch, n) -> x (batch, time, n), without gradients and without the drives in memory; ``None`` where
    the module docstring leaves it to torch. For one input the drive's two products and their sum are those of
    ``u @ G0.T + u @ G1.T``, so the states are the recurrence's on those drives to the last bit."""
    library = _usable(Phi, G0, G1, u, x0)
    if library is None:
        return None
    Phi, G0, G1, u, x0 = (x.detach().contiguous() for x in (Phi, G0, G1, u, x0))
    batch, time, m = u.shape
    n = Phi.shape[0]
    x = torch.empty(batch, time, n, dtype=torch.float64)
    library.forced(batch, time - 1, n, m, Phi.data_ptr(), G0.data_ptr(), G1.data_ptr(), u.data_ptr(), x0.data_ptr(),
                   x.data_ptr())
    return x
