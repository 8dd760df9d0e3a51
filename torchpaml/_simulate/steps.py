r"""The one-step methods of the shooting engine: RK4 (explicit) and TR-BDF2 (implicit), each as a sweep.

:class:`~torchpaml.RK4` and :class:`~torchpaml.TRBDF2` each call their own sweep here (``solver.sweep``); this module
knows no solver class.

A sweep integrates rows of states through the steps of a segment (:class:`~torchpaml._simulate.shooting`'s
layout). The states are kept state-major (each state's column contiguous, see
:func:`~torchpaml.state_vector`). Each step has its stage times and inputs at the fractions
$j/m$ and $(j + c)/m$ of the sample interval ($m$ substeps, $c$ the method's ``middle``), laid out once
per solve, and its step coefficients.

**TR-BDF2's stages** solve $z = a + d\,h\,f(t_z, z)$ (:class:`~torchpaml.TRBDF2`) by
Newton's method, the Jacobian $\partial f/\partial x$ by reverse mode (one backward pass per state), until
the update is below :data:`NEWTON_TOL` of the state's scale. In a sweep that records gradients the converged $z^*$ is corrected once more,

$$ z = z^* - M^{-1}\bigl(z^* - a - d\,h\,f(t_z, z^*)\bigr), \qquad M = I - d\,h\,\partial f/\partial x
   \ \text{(held constant)}, $$

$M$ the last Newton iteration's (its point within :data:`NEWTON_TOL` of $z^*$), whose value is $z^*$ and whose
derivative in the parameters and in $a$ is the implicit function theorem's,
$M^{-1}(\partial a + d\,h\,\partial f/\partial\theta)$: exact gradients by reverse mode.
"""

from __future__ import annotations

import torch

from torchpaml._simulate.dynamics import Dynamics
from torchpaml._errors import SimulationError
__all__ = ["GAMMA", "RK4_COEFFICIENTS", "TRBDF2_COEFFICIENTS", "rate_and_jacobian", "rk4_sweep", "trbdf2_sweep"]

#: TR-BDF2's split of a step: the trapezoid covers the first ``GAMMA`` of it, BDF2 the rest.
GAMMA = 2 - 2**0.5
#: TR-BDF2's implicit coefficient $d$ (both stages).
D = 1 - 2**-0.5
#: The BDF2 stage's weights of $x_\gamma$ and of $x$.
BDF_NEW, BDF_OLD = 1 / (GAMMA * (2 - GAMMA)), (1 - GAMMA) ** 2 / (GAMMA * (2 - GAMMA))
#: Each method's step coefficients, as multiples of the substep: RK4's half, whole and sixth; TR-BDF2's d.
RK4_COEFFICIENTS, TRBDF2_COEFFICIENTS = (0.5, 1.0, 1 / 6), (D,)
#: Newton's stopping update in a TR-BDF2 stage, relative to the state's scale.
NEWTON_TOL = 1e-12
#: Newton iterations after which a stage stops: converged where its last update is below :data:`STALL_TOL`, else it
#: raises.
MAX_ITERATIONS = 20
#: The last update, relative to the state's scale, at which a stage that has run :data:`MAX_ITERATIONS` counts as
#: solved: far below any step's own error, where a stiff stage across a ``clamp`` (a fast spill on a long step)
#: cycles by 1e-12 of the state in its ill-conditioned solve instead of reaching :data:`NEWTON_TOL`.
STALL_TOL = 1e-9
#: Halvings of a Newton step that does not lower the residual (a backtracking line search).
HALVINGS = 10


def _state_major(x: torch.Tensor) -> torch.Tensor:
    return x.t().contiguous().t()


def rk4_sweep(physics: Dynamics, x: torch.Tensor, stages, substeps: int) -> torch.Tensor:
    """Integrate the rows of ``x`` (rows, n) through the steps of ``stages`` by RK4 at ``substeps``.

    Returns:
        states at the step boundaries, (n, L + 1, rows), contiguous.
    """
    x = _state_major(x)
    states = [x.t()]
    f = physics.derivative
    for times, inputs, (half, step, sixth) in stages:
        for j in range(substeps):
            (t_a, t_mid, t_c), (u_a, u_mid, u_c) = times[2 * j : 2 * j + 3], inputs[2 * j : 2 * j + 3]
            k1 = f(t_a, x, u_a)
            k2 = f(t_mid, torch.addcmul(x, half, k1), u_mid)
            k3 = f(t_mid, torch.addcmul(x, half, k2), u_mid)
            k4 = f(t_c, torch.addcmul(x, step, k3), u_c)
            x = torch.addcmul(x, sixth, torch.add(k1 + k4, k2 + k3, alpha=2))
        states.append(x.t())
    return torch.stack(states, dim=1)


def rate_and_jacobian(f, t: torch.Tensor, z: torch.Tensor, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """$f(t, z, u)$ (R, n) and its Jacobian $\\partial f/\\partial x$ (R, n, n), by reverse mode (one backward pass
    per state: the rows are independent), without gradients. Exact on each side of a corner of the physics (a
    ``clamp``), where differences would mix the two slopes and stall Newton."""
    try:
        with torch.enable_grad():
            x = z.detach().requires_grad_(True)
            rates = f(t, x, u)
            rows = [torch.autograd.grad(rates[:, i].sum(), x, retain_graph=i < z.shape[1] - 1)[0]
                    for i in range(z.shape[1])]
    except RuntimeError as error:
        if "functorch" not in str(error):
            raise
        raise NotImplementedError(
            "TRBDF2's Newton differentiates the physics by reverse mode, which cannot run inside torch.func "
            "transforms (jvp, vmap): differentiate a TRBDF2 simulation by reverse mode (backward), or take "
            "output_jacobian's columns") from None
    # a slope that is infinite at a point (a square root at zero) is left out of that Newton step
    return rates.detach(), torch.stack(rows, dim=1).nan_to_num(0.0, 0.0, 0.0)


def _stage(f, t: torch.Tensor, u: torch.Tensor, a: torch.Tensor, dh: torch.Tensor, z: torch.Tensor,
           scale: torch.Tensor) -> torch.Tensor:
    r"""$z$ with $z = a + d h f(t, z)$, by Newton from ``z`` (module docstring); rows (R,), (R, m), (R, n), (R, 1).

    Each Newton step is halved, row by row, until it lowers the row's residual $\|z - a - d h f\|_\infty$ (a
    backtracking line search): where the physics is steep or bends sharply (a square root near zero, a
    ``clamp``), the full step can overshoot."""
    n = z.shape[1]
    eye = torch.eye(n, dtype=z.dtype)
    anchor, tracked = a.detach(), torch.is_grad_enabled()

    def residual(point: torch.Tensor, rates: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        g = point - anchor - dh * rates
        return g, (g.abs() / scale).amax(dim=1).nan_to_num(0.0, 0.0, 0.0)  # a blown-up row: the outer Newton's

    with torch.no_grad():
        for _ in range(MAX_ITERATIONS):
            rates, J = rate_and_jacobian(f, t, z, u)
            g, size = residual(z, rates)
            M = eye - dh[..., None] * J
            update = torch.linalg.solve(M, g)
            step = torch.ones_like(size)
            for _ in range(HALVINGS):
                trial = z - step[:, None] * update
                _, trial_size = residual(trial, f(t, trial, u))
                worse = (trial_size > size * (1 - 1e-4 * step)) & (trial_size > NEWTON_TOL)  # not at round-off
                if not bool(worse.any()):
                    break
                step = torch.where(worse, step / 2, step)
            z = trial
            change = float(((step[:, None] * update).abs() / scale).nan_to_num(0.0, 0.0, 0.0).max())
            if change <= NEWTON_TOL:
                break
        else:
            if change > STALL_TOL:
                raise SimulationError(
                    f"TR-BDF2's Newton did not converge in {MAX_ITERATIONS} iterations at t = {float(t[0]):.4g} s "
                    f"(last update {change:.3g} of the state's scale): the physics is not smooth enough there, or "
                    f"blows up")
    if not tracked:
        return z
    # M of the last iteration: its point is within NEWTON_TOL of z
    return z - torch.linalg.solve(M, z - a - dh * f(t, z, u))


def trbdf2_sweep(physics: Dynamics, x: torch.Tensor, stages, substeps: int) -> torch.Tensor:
    """Integrate the rows of ``x`` (rows, n) through the steps of ``stages`` by TR-BDF2 at ``substeps``; returns as
    :func:`rk4_sweep`."""
    x = _state_major(x)
    states = [x.t()]
    f = physics.derivative
    scale = x.detach().abs().amax(dim=0).clamp(min=1.0)
    for times, inputs, (dh,) in stages:
        for j in range(substeps):
            (t_a, t_g, t_c), (u_a, u_g, u_c) = times[2 * j : 2 * j + 3], inputs[2 * j : 2 * j + 3]
            middle = _stage(f, t_g, u_g, torch.addcmul(x, dh, f(t_a, x, u_a)), dh, x.detach(), scale)
            x = _stage(f, t_c, u_c, BDF_NEW * middle - BDF_OLD * x, dh, middle.detach(), scale)
        states.append(x.t())
    return torch.stack(states, dim=1)
