import os

import pytest
import torch

torch.set_default_dtype(torch.float64)
if os.environ.get("PYTEST_XDIST_WORKER"):  # `-n 2`: one thread per worker, not two workers of two threads each
    torch.set_num_threads(1)
    for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # and per command it runs
        os.environ.setdefault(variable, "1")


@pytest.fixture
def grid():
    """A 20 s record at 100 Hz: long enough for dynamics, short enough for fast tests."""
    from torchpaml._signals import time_grid

    return time_grid(20.0, 0.01)
