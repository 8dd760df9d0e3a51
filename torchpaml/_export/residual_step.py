r"""The Chebyshev-Hammerstein residual's one-step map as expressions, for the ONNX export of a hybrid.

The residual filters each feature $\varphi_k = T_{2j+1}(u_i/\alpha)$ through the companion realisation of $1/D(s)$,
discretised exactly at the records' sampling interval $h$ with the input linear between samples
(:func:`~torchpaml._simulate.lti.discretize`, as the residual itself simulates), from zero states:

$$ z_{k}^{+} = \Phi z_k + \Gamma_0\,\varphi_k(u) + \Gamma_1\,\varphi_k(u^{+}), \qquad
   r = \sum_k c_k^\top z_k + d_k\,\varphi_k(u), $$

$u^{+}$ the input at the next sample. The graph is exact at that $h$ only.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy
import torch

from torchpaml._residual.chebyshev_hammerstein import ChebyshevHammerstein
from torchpaml._simulate.lti import discretize

__all__ = ["ResidualStep", "residual_step"]


@dataclass(frozen=True)
class ResidualStep:
    """The residual's states $z$, the next input's symbols $u^+$, $z^+$ and $r$ as expressions (module docstring)."""

    states: tuple[sympy.Symbol, ...]
    following: tuple[sympy.Symbol, ...]
    next_states: tuple[sympy.Expr, ...]
    output: tuple[sympy.Expr, ...]


def _numbers(tensor: torch.Tensor) -> list:
    return [sympy.Float(repr(float(v))) for v in tensor.detach().reshape(-1)]


def residual_step(residual: ChebyshevHammerstein, inputs: tuple[sympy.Symbol, ...], h: float) -> ResidualStep:
    """The one-step map of ``residual`` (module docstring) on the input symbols ``inputs`` at the interval ``h``."""
    following = tuple(sympy.Symbol(f"{s.name}_next", real=True) for s in inputs)
    features = lambda values: [sympy.expand(sympy.chebyshevt(d, v / residual.alpha))  # noqa: E731
                               for v in values for d in residual.degrees]
    now, later = features(inputs), features(following)
    m = residual.order
    D = residual.denominator().detach()
    A = torch.cat([torch.eye(m, dtype=torch.float64)[1:], -D.flip(0)[:m][None]])
    B = torch.zeros(m, 1, dtype=torch.float64)
    B[-1, 0] = 1.0
    Phi, G0, G1 = (sympy.Matrix(*M.shape, _numbers(M)) for M in discretize(A, B, h, "foh"))
    states, next_states = [], []
    for k in range(len(now)):
        z = sympy.Matrix([sympy.Symbol(f"z{k}_{j}", real=True) for j in range(m)])
        states += list(z)
        next_states += list(Phi * z + G0 * now[k] + G1 * later[k])
    coefficients = residual.coefficients().detach().reshape(residual.outputs, len(now), m + 1)
    output = []
    for o in range(residual.outputs):
        c = _numbers(coefficients[o])
        output.append(sum(c[k * (m + 1) + j] * states[k * m + j] for k in range(len(now)) for j in range(m))
                      + sum(c[k * (m + 1) + m] * now[k] for k in range(len(now))))
    return ResidualStep(tuple(states), following, tuple(next_states), tuple(output))
