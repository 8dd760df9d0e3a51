"""Simulation: exact LTI discretisation, torchdiffeq ODE integration, differentiable IIR filtering."""

from torchpaml._simulate.iir import iir_filter
from torchpaml._simulate.interpolation import LinearInterpolant
from torchpaml._grid import HOLDS, uniform_step
from torchpaml._simulate.lti import discretize, simulate_lti
from torchpaml._simulate.sensitivity import output_jacobian, raw_parameters
from torchpaml._simulate.simulator import simulate
from torchpaml._simulate.solvers import RK4, TRBDF2, Auto, Dopri5, Exact, Solver
from torchpaml._simulate.warm import WarmStart

__all__ = ["iir_filter", "LinearInterpolant", "HOLDS", "discretize", "simulate_lti", "simulate", "uniform_step", "output_jacobian", "raw_parameters", "WarmStart",
           "Auto", "Dopri5", "Exact", "RK4", "Solver", "TRBDF2"]
