"""Reference solutions the numerical tests compare against."""

import numpy as np
import sympy
import torch
from scipy.integrate import solve_ivp

from torchpaml._symbolic.trace import symbolic_maps


def closed_form_rate(physics):
    """``physics``' rate as a plain function ``(state, drive) -> dx/dt`` (numpy), lambdified from its closed form
    (:func:`~torchpaml._symbolic.trace.symbolic_maps`, itself checked against the physics to 1e-12 in
    ``test_symbolic_maps.py``): scipy then integrates without a torch call per stage. One input, no explicit time."""
    t = sympy.Symbol("t")
    x = np.array([[sympy.Symbol(f"x{i}") for i in range(physics.state_dim)]], dtype=object)
    u = np.array([[sympy.Symbol("u")]], dtype=object)
    rates, _ = symbolic_maps(physics, {"t": np.array([t], dtype=object), "x": x, "u": u})
    assert not any(t in sympy.sympify(rate).free_symbols for rate in rates[0]), "the rate depends on time"
    rate = sympy.lambdify([list(x[0]), u[0, 0]], list(rates[0]), modules="math")
    return lambda state, drive: np.array(rate(state, drive), dtype=float)


def oracle(physics, t, u, method: str = "DOP853", rate=None):
    """The output (1, time, 1) by scipy's ``method`` (DOP853; Radau for stiff physics) at rtol 1e-12, interval by
    interval, the input linear in each.

    ``rate(state, drive) -> dx/dt`` (numpy, shape (n,)) is the physics' rate written out by hand, where a test wants
    the reference fast and independent of the physics' code; by default the physics' own ``derivative`` is used.
    """
    x = physics.initial_state(1)[0].numpy()
    states = [x]
    for k in range(len(t) - 1):
        t0, t1, u0, u1 = float(t[k]), float(t[k + 1]), float(u[0, k, 0]), float(u[0, k + 1, 0])

        def interval_rate(time, state, t0=t0, t1=t1, u0=u0, u1=u1):
            drive = u0 + (time - t0) * (u1 - u0) / (t1 - t0)
            if rate is not None:
                return rate(state, drive)
            with torch.no_grad():
                drive = torch.tensor([[drive]], dtype=torch.float64)
                return physics.derivative(torch.tensor([time]), torch.tensor(state)[None], drive)[0].numpy()

        x = solve_ivp(interval_rate, (t0, t1), x, method=method, rtol=1e-12, atol=1e-14).y[:, -1]
        states.append(x)
    with torch.no_grad():
        return physics.output(torch.tensor(np.array(states))[None], u)
