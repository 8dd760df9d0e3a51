r"""Where a tracker's filter starts, and how much the model may drift per sample: both from the stream and the fit.

**The start** (:func:`estimated_start`). A device is often in motion when its stream begins. The initial state
$\hat x_0$ is the one that best explains the stream's first window of samples, the parameters fixed
(:func:`~torchpaml.estimate_initial_state`, what ``Estimate()`` does for records), and its covariance is the
Gauss-Newton one of that estimate,

$$ P_0 = \bigl(J^\top R^{-1} J + \Lambda\bigr)^{-1}, \qquad J = \partial \hat y_{0..W-1} / \partial x_0, $$

$J$ (W p, n) by the solver's own sensitivities, $R$ the measurement noise. $\Lambda = \operatorname{diag}(1/s_i^2)$
is a weak prior that keeps $P_0$ finite for a state the window does not determine (an effect's state that the
output does not show yet): $s_i$ is ten times the larger of the state's range over the window and $|\hat x_{0,i}|$
(at least $10^{-6}$ of the largest such scale). The filter then predicts through the window without using its
samples again (they made $\hat x_0$), and its detector starts after it.

**The process noise** (:func:`process_noise_of_fit`). A fitted model is off by its parameters' errors, and a
filter that trusts it fully lets that error build up in the state: on an integrating plant (a rigid body, its
position measured) the open-loop drift grows without bound, and the detector alarms on a device that did not change.
The process noise is the state error that the fit's uncertainty allows over the detector's window,

$$ Q = W \cdot \frac{1}{W}\sum_{k} G_k\,\Sigma\,G_k^\top, \qquad G_k = \partial \Phi(x_k, u_k, u_{k+1};
   \theta) / \partial\theta, $$

$\Phi$ the filter's RK4 step, $x_k$ the $W$ states along the window from $\hat x_0$, $\Sigma$ the fit's
covariance of the parameters (standard errors and correlation, ``FittedModel.uncertainty``) and $G_k$ by forward
differences. The mean is one sample's push; the factor $W$ is there because a parameter error is no white noise:
it pushes the state the same way sample after sample, so over the window it moves the state $W$ times one push,
where white noise of that size moves it $\sqrt W$ times, and the random walk the filter assumes must cover that
drift. (Measured on a fitted rigid body with Coulomb friction, its position measured, 120 s streams: without the
factor the detector alarmed on the unchanged device after 9 to 20 s; with it the window sum's mean is its
$\chi^2$ mean, $pW$, to 1 %; ``tests/diagnosis/test_tracking_goals.py``.)
A parameter change within the fit's uncertainty is absorbed by the filter; one beyond it shows in the innovation.
A model without uncertainty (not saved from a fit) gets $Q = 0$; a parameter the fit did not determine (infinite
standard error) is left out.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import torch

from torchpaml._data import Record
from torchpaml._data.simulation import record_jacobian
from torchpaml._errors import TorchpamlError
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._fit.physics_fit import estimate_initial_state
from torchpaml._simulate.solvers import RK4

__all__ = ["estimated_start", "process_noise_of_fit", "states_along"]

#: The prior's width (module docstring), in units of each state's own scale over the window.
PRIOR_WIDTH = 10.0


def states_along(model: FittedModel, window: Record, x0: np.ndarray, substeps: int) -> np.ndarray:
    """The states (time, n_state) along ``window`` from ``x0`` by the filter's RK4 at ``substeps``."""
    with torch.no_grad():
        start = torch.as_tensor(x0, dtype=torch.float64)[None]
        return RK4(substeps=substeps).states(model.physics, window.elapsed, window.u[None], start,
                                             hold=window.hold)[0].numpy()


def estimated_start(model: FittedModel, window: Record, noise: np.ndarray, substeps: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(x0, P0)``: the initial state (n_state,) that best explains ``window`` and its covariance (module
    docstring); ``noise``: each output's standard deviation; ``substeps``: the filter's RK4 substeps."""
    solver = RK4(substeps=substeps)
    x0 = estimate_initial_state(model.physics, window, solver=solver)
    with torch.no_grad():
        _, J = record_jacobian(model.physics, [], window, x0, initial_state=True, solver=solver)
    weighted = J[0].numpy() / noise[None, :, None]  # (time, n_y, n)
    information = np.einsum("tyi,tyj->ij", weighted, weighted)
    values = states_along(model, window, x0.numpy(), substeps)
    scale = np.maximum(np.ptp(values, axis=0), np.abs(x0.numpy()))
    scale = PRIOR_WIDTH * np.maximum(scale, 1e-6 * max(float(scale.max()), 1e-300))
    covariance = np.linalg.inv(information + np.diag(1.0 / scale**2))
    return x0.numpy().copy(), (covariance + covariance.T) / 2


def process_noise_of_fit(model: FittedModel, states: np.ndarray, window: Record, substeps: int,
                         samples: int) -> np.ndarray:
    """$Q$ (n_state, n_state) of the module docstring, from the states along ``window``, for a detector window of
    ``samples`` samples ($W$); zeros where the model has no uncertainty."""
    n = model.physics.state_dim
    uncertainty = model.uncertainty
    values = model.physics.physical_parameters()
    names = [] if uncertainty is None else [k for k in uncertainty.std if k in values
                                            and math.isfinite(uncertainty.std[k]) and uncertainty.std[k] > 0]
    if not names or len(window.t) < 2:
        return np.zeros((n, n))
    solver = RK4(substeps=substeps)
    pairs = torch.stack([window.u[:-1], window.u[1:]], dim=1)  # (time - 1, 2, n_u): each step's two inputs
    start = torch.from_numpy(states[:-1].copy())
    t = torch.stack([torch.zeros(()), window.t[1] - window.t[0]]).to(torch.float64)

    def step(physics) -> torch.Tensor:
        with torch.no_grad():
            return solver.states(physics, t, pairs, start, hold=window.hold)[:, 1]

    nominal = step(model.physics)
    columns = []
    for name in names:
        delta = 1e-6 * max(abs(values[name]), uncertainty.std[name])
        moved = copy.deepcopy(model.physics)
        try:
            moved.assign(**{name: values[name] + delta})
        except TorchpamlError:  # at the upper edge of its constraint: the step goes down
            delta = -delta
            moved.assign(**{name: values[name] + delta})
        columns.append((step(moved) - nominal) / delta)
    G = torch.stack(columns, dim=-1).numpy()  # (time - 1, n, p)
    order = list(uncertainty.std)
    index = [order.index(name) for name in names]
    std = np.array([uncertainty.std[name] for name in names])
    sigma = std[:, None] * uncertainty.correlation.numpy()[np.ix_(index, index)] * std[None, :]
    Q = samples * np.einsum("kip,pq,kjq->ij", G, sigma, G) / len(G)
    return (Q + Q.T) / 2
