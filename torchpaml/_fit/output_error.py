"""Gradient-based output-error minimisation with torch.optim, shared by every fitting stage."""

from __future__ import annotations

from collections.abc import Callable

import torch

__all__ = ["minimize_output_error"]


def minimize_output_error(
    predict: Callable[[], torch.Tensor],
    target: torch.Tensor,
    parameters: list[torch.nn.Parameter],
    *,
    optimizer: str = "lbfgs",
    max_iter: int = 100,
    lr: float = 1e-2,
) -> tuple[float, int]:
    r"""Minimise $\|y - \mathrm{predict}()\|^2 / \|y\|^2$ over ``parameters``; returns (final loss, iterations).

    ``optimizer="lbfgs"``: ``torch.optim.LBFGS`` with a strong-Wolfe line search (for a handful of
    smooth physical or pole parameters). ``optimizer="adam"``: ``max_iter`` Adam steps (for networks).
    """
    scale = torch.sum(target.detach() ** 2)

    def loss_fn():
        return torch.sum((target - predict()) ** 2) / scale

    if optimizer == "lbfgs":
        opt = torch.optim.LBFGS(parameters, lr=1.0, max_iter=max_iter, line_search_fn="strong_wolfe",
                                tolerance_grad=1e-12, tolerance_change=1e-14)

        def closure():
            opt.zero_grad()
            loss = loss_fn()
            loss.backward()
            return loss

        opt.step(closure)
        iterations = opt.state[opt._params[0]].get("n_iter", 0)
    elif optimizer == "adam":
        opt = torch.optim.Adam(parameters, lr=lr)
        for _ in range(max_iter):
            opt.zero_grad()
            loss = loss_fn()
            loss.backward()
            opt.step()
        iterations = max_iter
    else:
        raise ValueError(f"optimizer must be 'lbfgs' or 'adam', got {optimizer!r}")
    with torch.no_grad():
        return float(loss_fn()), int(iterations)
