"""Signals: shapes, seeding, the paper's pseudorandom construction, amplitude scaling."""

import torch

from torchpaml._signals import chirp, cosine, multisine, pseudorandom, pseudorandom_knots, sine, time_grid


def test_time_grid_spacing_and_length():
    t = time_grid(80.0, 0.01)
    assert t.shape == (8000,) and t.dtype == torch.float64
    assert float(t[1] - t[0]) == 0.01


def test_shapes_are_batch_time_channel(grid):
    assert sine(grid, 1.0, 1.0).shape == (1, len(grid), 1)
    assert cosine(grid, 1.0, 1.0).shape == (1, len(grid), 1)
    assert pseudorandom(grid, 1.0, batch=3).shape == (3, len(grid), 1)
    assert multisine(grid, 1.0, [0.1, 0.2], batch=2).shape == (2, len(grid), 1)
    assert chirp(grid, 1.0, 0.05, 1.0).shape == (1, len(grid), 1)


def test_pseudorandom_is_seeded_bounded_and_linear_between_knots(grid):
    u = pseudorandom(grid, 4.0, batch=2, seed=5)
    assert torch.equal(u, pseudorandom(grid, 4.0, batch=2, seed=5))
    assert not torch.equal(u, pseudorandom(grid, 4.0, batch=2, seed=6))
    assert float(u.abs().max()) <= 4.0
    # between knots (every 0.8 s = 80 samples) the second difference vanishes
    second = u[0, 2:, 0] - 2 * u[0, 1:-1, 0] + u[0, :-2, 0]
    interior = torch.ones_like(second, dtype=torch.bool)
    interior[79::80] = False  # sample k+1 = 80 m sits on a knot
    assert float(second[interior].abs().max()) < 1e-12
    assert float(second[~interior].abs().max()) > 1e-3
    assert torch.allclose(pseudorandom_knots(grid)[:3], torch.tensor([0.0, 0.8, 1.6]))


def test_multisine_peak_and_seed(grid):
    u = multisine(grid, 2.5, [0.1, 0.3, 0.7], batch=2, seed=1)
    assert torch.allclose(u.abs().amax(dim=1), torch.full((2, 1), 2.5))
    assert not torch.equal(u[0], u[1])


def test_chirp_sweeps_between_the_end_frequencies():
    t = time_grid(100.0, 0.01)
    u = chirp(t, 1.0, 0.1, 1.0)[0, :, 0]
    crossings = lambda x: int(((x[1:] * x[:-1]) < 0).sum())  # noqa: E731
    first, last = u[: len(u) // 10], u[-len(u) // 10 :]
    assert crossings(last) > 4 * crossings(first)
