"""The simulation engine's pieces, for code that builds on it: the protocol a model implements for the solvers
(``Dynamics``), the initial state a model starts from, the warm start of the shooting engine, output Jacobians in
the raw parameters, and the differentiable IIR filter."""

from torchpaml._simulate import WarmStart, iir_filter, output_jacobian, raw_parameters
from torchpaml._simulate.dynamics import Dynamics, complete_state

__all__ = ["Dynamics", "WarmStart", "complete_state", "iir_filter", "output_jacobian", "raw_parameters"]
