"""Continuous-time input from samples: the piecewise-linear interpolant (first-order hold)."""

from __future__ import annotations

import torch

__all__ = ["LinearInterpolant"]


class LinearInterpolant:
    r"""$u(\tau) = u_k + \frac{\tau - t_k}{t_{k+1} - t_k}(u_{k+1} - u_k)$ for $t_k \le \tau \le t_{k+1}$.

    This is the same hold the exact discretisation assumes, so the ODE and exact simulators see one
    input. Outside $[t_0, t_{N-1}]$ the end samples are held. Kinks sit at the sample times, which
    the adaptive solvers are told to step on.

    Args:
        t: sample times, shape (time,), strictly increasing.
        u: samples, shape (batch, time, channel).
    """

    def __init__(self, t: torch.Tensor, u: torch.Tensor):
        self.t, self.u = t, u
        self._slope = (u[:, 1:] - u[:, :-1]) / (t[1:] - t[:-1])[None, :, None]
        steps = torch.diff(t)
        h = float(steps.mean())
        self._grid = (float(t[0]), h) if float((steps - h).abs().max()) <= 1e-9 * h else None

    def __call__(self, tau: torch.Tensor) -> torch.Tensor:
        """Input at time ``tau`` (scalar tensor), shape (batch, channel).

        On a uniform grid the interval is found by arithmetic on Python floats (a solver calls this
        at every stage, and a tensor search costs about as much as the rest of a small vector field).
        """
        last = len(self.t) - 2
        if self._grid is not None:
            t0, h = self._grid
            position = (float(tau.detach()) - t0) / h
            k = min(max(int(position), 0), last)
            return self.u[:, k] + (min(max(position - k, 0.0), 1.0) * h) * self._slope[:, k]
        k = (torch.searchsorted(self.t, tau.detach().reshape(1), right=True) - 1).clamp(0, last)[0]
        dtau = (tau - self.t[k]).clamp(min=0.0, max=float(self.t[k + 1] - self.t[k]))
        return self.u[:, k] + dtau * self._slope[:, k]
