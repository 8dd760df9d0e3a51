"""One arithmetic path per fit: every reduction of a fit on one thread.

A sum split over threads is added in an order that depends on the thread count, and a nonconvex fit whose steps
differ in the last digit can end in another optimum. While a fit runs, the BLAS and OpenMP pools that numpy and
scipy's least-squares step use (through ``threadpoolctl``) and torch's own intra-op pool are held at one thread, so
the same records give the same numbers on a machine of one core or of many. The compiled simulation and Jacobian are
sequential C already.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import torch
from threadpoolctl import threadpool_limits

__all__ = ["one_thread"]


@contextmanager
def one_thread() -> Iterator[None]:
    """Hold numpy's, scipy's and torch's thread pools at one thread inside the block (module docstring)."""
    threads = torch.get_num_threads()
    with threadpool_limits(limits=1):
        torch.set_num_threads(1)
        try:
            yield
        finally:
            torch.set_num_threads(threads)
