import pytest
import torch

torch.set_default_dtype(torch.float64)


@pytest.fixture
def grid():
    """A 20 s record at 100 Hz: long enough for dynamics, short enough for fast tests."""
    from torchpaml.signals import time_grid

    return time_grid(20.0, 0.01)
