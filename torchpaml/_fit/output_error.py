"""Gradient-based output-error minimisation with torch.optim, shared by every fitting stage."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import torch

from torchpaml._budget import Budget
from torchpaml._errors import ConfigurationError

__all__ = ["minimize_output_error"]


def minimize_output_error(
    predict: Callable[[], torch.Tensor],
    target: torch.Tensor,
    parameters: list[torch.nn.Parameter],
    *,
    optimizer: str = "lbfgs",
    max_iter: int = 100,
    lr: float = 1e-2,
    rtol: float | None = None,
    budget: Budget | None = None,
) -> tuple[float, int]:
    r"""Minimise $\|y - \mathrm{predict}()\|^2 / \|y\|^2$ over ``parameters``; returns (final loss, iterations).

    ``budget`` (a :class:`~torchpaml.Budget`) is told of every evaluation of the loss: it prints progress lines and
    raises :class:`~torchpaml.OverBudget` past its limit, leaving ``parameters`` where the search stood.

    ``optimizer="lbfgs"``: ``torch.optim.LBFGS`` with a strong-Wolfe line search (for a handful of
    smooth physical or pole parameters). It stops when a step changes the loss by less than 1e-14 or, with
    ``rtol``, by less than ``rtol`` times the loss: in rounds, each with the tolerance ``rtol`` times the loss at
    its start, repeated while a round divides the loss by 10 or more (a fit that explains nearly everything
    goes on to its last digits). ``optimizer="adam"``: ``max_iter`` Adam steps (for networks).
    """
    scale = torch.sum(target.detach() ** 2)
    lowest = math.inf

    def loss_fn():
        nonlocal lowest
        began = time.perf_counter()
        loss = torch.sum((target - predict()) ** 2) / scale
        if budget is not None:
            lowest = min(lowest, float(loss.detach()))
            budget.check(lowest, time.perf_counter() - began)
        return loss

    if optimizer == "lbfgs":
        iterations, start = 0, None
        while iterations < max_iter:
            if rtol is not None:
                with torch.no_grad():
                    start = float(loss_fn())
            opt = torch.optim.LBFGS(parameters, lr=1.0, max_iter=max_iter - iterations, line_search_fn="strong_wolfe",
                                    tolerance_grad=1e-12, tolerance_change=1e-14 if rtol is None else rtol * start)

            def closure():
                opt.zero_grad()
                loss = loss_fn()
                loss.backward()
                return loss

            opt.step(closure)
            done = opt.state[opt._params[0]].get("n_iter", 0)
            iterations += done
            if rtol is None or done == 0:
                break
            with torch.no_grad():
                if float(loss_fn()) > start / 10:
                    break
    elif optimizer == "adam":
        opt = torch.optim.Adam(parameters, lr=lr)
        for _ in range(max_iter):
            opt.zero_grad()
            loss = loss_fn()
            loss.backward()
            opt.step()
        iterations = max_iter
    else:
        raise ConfigurationError(f"optimizer must be 'lbfgs' or 'adam', got {optimizer!r}")
    with torch.no_grad():
        return float(loss_fn()), int(iterations)
