"""Simulation: the solvers (exact LTI discretisation, RK4 and TR-BDF2 in a parallel shooting engine, torchdiffeq's
Dopri5), output Jacobians, and differentiable IIR filtering."""

from torchpaml._simulate.iir import iir_filter
from torchpaml._simulate.sensitivity import raw_parameters
from torchpaml._simulate.simulator import output_jacobian, simulate
from torchpaml._simulate.solvers import RK4, TRBDF2, Auto, Dopri5, Exact, Solver
from torchpaml._simulate.warm import WarmStart

__all__ = ["Auto", "Dopri5", "Exact", "RK4", "Solver", "TRBDF2", "WarmStart", "iir_filter", "output_jacobian",
           "raw_parameters", "simulate"]
