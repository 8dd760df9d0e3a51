"""Reference solutions the numerical tests compare against."""

import numpy as np
import torch
from scipy.integrate import solve_ivp


def oracle(physics, t, u, method: str = "DOP853"):
    """The output (1, time, 1) by scipy's ``method`` (DOP853; Radau for stiff physics) at rtol 1e-12, interval by
    interval, the input linear in each."""
    x = physics.initial_state(1)[0].numpy()
    states = [x]
    for k in range(len(t) - 1):
        t0, t1, u0, u1 = float(t[k]), float(t[k + 1]), float(u[0, k, 0]), float(u[0, k + 1, 0])

        def rate(time, state, t0=t0, t1=t1, u0=u0, u1=u1):
            drive = torch.tensor([[u0 + (time - t0) * (u1 - u0) / (t1 - t0)]], dtype=torch.float64)
            with torch.no_grad():
                return physics.derivative(torch.tensor([time]), torch.tensor(state)[None], drive)[0].numpy()

        x = solve_ivp(rate, (t0, t1), x, method=method, rtol=1e-12, atol=1e-14).y[:, -1]
        states.append(x)
    with torch.no_grad():
        return physics.output(torch.tensor(np.array(states))[None], u)
